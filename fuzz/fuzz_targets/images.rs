// Image headers and depth PNGs. The first byte picks the reader.
#![no_main]
use libfuzzer_sys::fuzz_target;

#[path = "common.rs"]
mod common;

fuzz_target!(|data: &[u8]| {
    let Some((&pick, body)) = data.split_first() else {
        return;
    };
    if pick % 2 == 0 {
        drop(wgslam::dataset::frame::image_size(&common::as_file(
            "i.png", body,
        )));
    } else {
        drop(wgslam::dataset::frame::load_depth(&common::as_file(
            "d.png", body,
        )));
    }
});
