// Shared by the targets: the input written to a file named `name` in this process's
// scratch folder (the readers take paths, as the command line gives them).
use std::path::PathBuf;

pub fn as_file(name: &str, data: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("wgslam-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, data).unwrap();
    path
}
