// The params file (`--params`) and the batch manifest. The first byte picks the reader.
#![no_main]
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    let text = String::from_utf8_lossy(body);
    if pick % 2 == 0 {
        let _ = wgslam::fuzz_entry::params_toml(&text);
    } else {
        let path = std::path::Path::new("/wgslam-fuzz/batch.toml");
        let _ = wgslam::fuzz_entry::manifest(path, &text);
    }
});
