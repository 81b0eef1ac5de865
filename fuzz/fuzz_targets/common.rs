// Shared by the targets: the input written to a file named `name` in this process's
// scratch folder (the readers take paths, as the command line gives them), and the reader
// the input's first byte picks.
use std::path::{Path, PathBuf};

pub fn as_file(name: &str, data: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("wgslam-fuzz-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, data).unwrap();
    path
}

/// A reader of files: the file name it is given, and the reader (its result dropped).
pub type FileReader = (&'static str, fn(&Path));

/// Reads the rest of `data`, written to a file, with the reader its first byte picks.
pub fn read_picked(data: &[u8], readers: &[FileReader]) {
    if let Some((&pick, body)) = data.split_first() {
        let (name, read) = readers[pick as usize % readers.len()];
        read(&as_file(name, body));
    }
}
