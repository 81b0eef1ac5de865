//! The compute pipelines' cache across processes: wgpu's `PipelineCache` (Vulkan's
//! `VkPipelineCache`; adapters with `Features::PIPELINE_CACHE`), read from a file in the
//! user's cache folder when the device opens and written back when the last context on the
//! device is dropped, so a second process skips the driver's shader compilation.
//!
//! Not a cache of wgpu objects (a process builds each pipeline once anyway,
//! `GpuContext::cached`), and never a reason to fail: a missing file is an empty cache, a
//! corrupt one or one from another driver is ignored with a note on stderr, and a failure
//! to write is a note. The file is written whole or not at all (a temporary file beside
//! it, then a rename). [`CACHE_ENV`] moves it or switches it off.

use std::path::{Path, PathBuf};

/// Environment variable for the cache's folder: `off` (or `0`) switches the cache off;
/// another value is the folder; unset or empty, `$XDG_CACHE_HOME/wgslam`, else
/// `~/.cache/wgslam`.
pub const CACHE_ENV: &str = "WGSLAM_PIPELINE_CACHE";

/// The folder [`CACHE_ENV`] names (`None`: switched off, or no home folder to put it in).
/// This crate's unit tests keep theirs in the temporary folder (the integration tests set
/// [`CACHE_ENV`] to a folder of their own).
pub fn cache_folder() -> Option<PathBuf> {
    let var = |name: &str| std::env::var_os(name).filter(|v| !v.is_empty());
    if cfg!(test) && var(CACHE_ENV).is_none() {
        return Some(std::env::temp_dir().join("wgslam-unit-test-cache"));
    }
    match var(CACHE_ENV) {
        Some(v) if v == "off" || v == "0" => None,
        Some(v) => Some(PathBuf::from(v)),
        None => var("XDG_CACHE_HOME")
            .map(PathBuf::from)
            .or_else(|| var("HOME").map(|h| Path::new(&h).join(".cache")))
            .map(|c| c.join("wgslam")),
    }
}

/// The largest cache file read, bytes: a driver's cache of the ~40 pipelines wgslam builds
/// is kilobytes to a few megabytes, so a larger file is not one wgslam wrote.
pub const MAX_CACHE_BYTES: u64 = 256 << 20;

/// The cache file's bytes, refused (as an `InvalidData` error, which becomes a note) when
/// it is over [`MAX_CACHE_BYTES`]. Read here, not through `wgslam_data::io::input` (a floor
/// above this crate): it is the file this program writes, not an input.
fn read_bounded(path: &Path) -> std::io::Result<Vec<u8>> {
    use std::io::Read;
    let file = std::fs::File::open(path)?;
    let len = file.metadata()?.len();
    if len > MAX_CACHE_BYTES {
        return Err(std::io::Error::new(
            std::io::ErrorKind::InvalidData,
            format!("{len} bytes, over the {MAX_CACHE_BYTES} of any cache wgslam writes"),
        ));
    }
    let mut bytes = Vec::with_capacity(len as usize);
    file.take(MAX_CACHE_BYTES).read_to_end(&mut bytes)?;
    Ok(bytes)
}

/// A device's pipeline cache and the file it came from and goes back to.
pub struct DiskCache {
    /// Give it to every pipeline the device creates.
    pub cache: wgpu::PipelineCache,
    path: PathBuf,
    /// The bytes read at start (empty without a usable file): unchanged data is not
    /// written again.
    loaded: Vec<u8>,
}

impl DiskCache {
    /// The cache of `device` (created with `Features::PIPELINE_CACHE`) from its file in
    /// `folder`, keyed by adapter and driver (`wgpu::util::pipeline_cache_key`); `None`
    /// for adapters wgpu keeps no cache file for (anything but Vulkan). A file that is
    /// unreadable, corrupt or another driver's is ignored with a note.
    pub fn open(device: &wgpu::Device, info: &wgpu::AdapterInfo, folder: &Path) -> Option<Self> {
        let path = folder.join(wgpu::util::pipeline_cache_key(info)?);
        let loaded = match read_bounded(&path) {
            Ok(bytes) => bytes,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Vec::new(),
            Err(e) => {
                note(
                    &path,
                    &format!("cannot be read ({e}); starting an empty one"),
                );
                Vec::new()
            }
        };
        let create = |data: Option<&[u8]>| {
            // SAFETY: wgpu validates the data's header (wgpu version, adapter, driver, a
            // hash of the contents) before the driver sees it, and with `fallback: false`
            // reports any mismatch as the validation error handled below instead of
            // passing the bytes on.
            unsafe {
                device.create_pipeline_cache(&wgpu::PipelineCacheDescriptor {
                    label: Some("wgslam pipeline cache"),
                    data,
                    fallback: false,
                })
            }
        };
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let cache = create((!loaded.is_empty()).then_some(loaded.as_slice()));
        match super::wait::block_on(scope.pop()) {
            None => Some(DiskCache {
                cache,
                path,
                loaded,
            }),
            Some(e) => {
                // wgpu's text is several lines ("Validation Error", "Caused by:", ...); the
                // last says what is wrong with the data.
                let text = e.to_string();
                let why = text.lines().map(str::trim).rfind(|l| !l.is_empty());
                let why = why.unwrap_or("invalid data");
                note(
                    &path,
                    &format!("is not usable here ({why}); starting an empty one"),
                );
                Some(DiskCache {
                    cache: create(None),
                    path,
                    loaded: Vec::new(),
                })
            }
        }
    }

    /// Writes the cache back to its file when it holds anything new: a temporary file
    /// beside it, then a rename over it. A failure is a note, not an error.
    pub fn save(&self) {
        let Some(data) = self.cache.get_data() else {
            return;
        };
        if data.is_empty() || data == self.loaded {
            return;
        }
        if let Err(e) = write_whole(&self.path, &data) {
            note(
                &self.path,
                &format!("could not be written ({e}); it is left as it was"),
            );
        }
    }

    /// The cache's file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

impl Drop for DiskCache {
    fn drop(&mut self) {
        self.save();
    }
}

/// The note on stderr about the cache file `path`.
fn note(path: &Path, what: &str) {
    eprintln!("note: the pipeline cache {} {what}", path.display());
}

/// `bytes` into `path` through a temporary file in the same folder and a rename, so a
/// reader sees the old file or the new one, never a part.
fn write_whole(path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    let folder = path.parent().unwrap_or(Path::new("."));
    std::fs::create_dir_all(folder)?;
    let name = path.file_name().unwrap_or_default().to_string_lossy();
    let tmp = folder.join(format!(".{name}.tmp-{}", std::process::id()));
    let written = std::fs::write(&tmp, bytes).and_then(|()| std::fs::rename(&tmp, path));
    if written.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    written
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_write_replaces_the_file_whole_and_leaves_no_temporary_file() {
        let dir = std::env::temp_dir().join(format!("wgslam-cache-test-{}", std::process::id()));
        let path = dir.join("sub").join("cache_file");
        write_whole(&path, b"first").unwrap();
        write_whole(&path, b"second").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"second");
        let names: Vec<_> = std::fs::read_dir(path.parent().unwrap())
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert_eq!(names, ["cache_file"]);
        // A folder where the file should be: the write fails (a note for the caller).
        std::fs::create_dir_all(dir.join("taken")).unwrap();
        assert!(write_whole(&dir.join("taken"), b"x").is_err());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
