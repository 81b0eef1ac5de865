//! The readers the fuzz replay feeds, each with its small valid seed files: point clouds
//! (PLY, PCD, KITTI `.bin`, text), trajectories and matrix files, image headers and depth
//! PNGs, the dataset layouts' lists, `camera.json` and pose files (opened in memory, as a
//! folder would be), and the params and batch-manifest TOML.

use std::io::Cursor;
use std::path::{Path, PathBuf};

use wgslam::dataset::{open_in_memory, InMemoryFiles};

use super::Reader;
use crate::common;

/// A reader's name and what makes its seeds and the reader itself (called inside its test).
pub type Case = (&'static str, fn() -> (Vec<Vec<u8>>, Reader));

/// Where the in-memory sequences live (no file is written there).
const ROOT: &str = "/fuzz-replay/seq";

/// Stamp difference allowed when associating the in-memory sequences' streams, seconds.
const MAX_TIME_DIFF: f64 = 0.02;

/// A case whose reader reads one file: its name, the file's name, its seeds, the reader.
macro_rules! file_reader {
    ($name:literal, $file:literal, $seeds:expr, $read:path) => {
        ($name, || ($seeds, on_file($name, $file, $read)))
    };
}

pub const CASES: &[Case] = &[
    file_reader!("ply", "c.ply", ply_seeds(), wgslam::io::read_ply),
    file_reader!(
        "ply_xyz",
        "c.ply",
        ply_seeds(),
        wgslam::scan::read::read_ply_xyz
    ),
    file_reader!("pcd", "c.pcd", pcd_seeds(), wgslam::scan::read::read_pcd),
    file_reader!(
        "kitti_bin",
        "c.bin",
        vec![kitti_seed()],
        wgslam::scan::read::read_kitti_bin
    ),
    file_reader!(
        "xyz_text",
        "c.xyz",
        vec![b"1 2 3\n4.5 -5 6e-1\n# note\n7,8,9\n".to_vec()],
        wgslam::scan::read::read_xyz_text
    ),
    file_reader!(
        "cloud_by_extension",
        "c.pcd",
        pcd_seeds(),
        wgslam::scan::read::read_cloud
    ),
    file_reader!(
        "matrix4",
        "m.txt",
        vec![IDENTITY.to_vec()],
        wgslam::scan::read::read_matrix4
    ),
    file_reader!(
        "airsim_pose",
        "p.txt",
        vec![b"1.0, 2.0, -3.0\n0.0, 0.0, 0.0, 1.0\n".to_vec()],
        wgslam::scan::odometry::read_airsim_pose
    ),
    file_reader!(
        "tum_trajectory",
        "t.txt",
        vec![TUM_GT.to_vec()],
        wgslam::io::read_tum
    ),
    file_reader!(
        "depth_png",
        "d.png",
        vec![depth_png()],
        wgslam::dataset::frame::load_depth
    ),
    file_reader!(
        "image_size",
        "i.png",
        vec![rgb_png(), rgb_jpg()],
        wgslam::dataset::frame::image_size
    ),
    ("icl_associations", || in_folder(icl(), "associations.txt")),
    ("icl_camera_json", || in_folder(icl(), "camera.json")),
    ("tum_rgb_list", || in_folder(tum(), "rgb.txt")),
    ("tum_depth_list", || in_folder(tum(), "depth.txt")),
    ("tum_groundtruth", || in_folder(tum(), "groundtruth.txt")),
    ("eth3d_associated", || in_folder(eth3d(), "associated.txt")),
    ("eth3d_calibration", || {
        in_folder(eth3d(), "calibration.txt")
    }),
    ("scannet_pose", || in_folder(scannet(), "pose/0.txt")),
    ("scannet_intrinsic", || {
        in_folder(scannet(), "intrinsic/intrinsic_depth.txt")
    }),
    ("params_toml", || {
        (
            vec![PARAMS.to_vec()],
            Box::new(|b: &[u8]| wgslam::fuzz_entry::params_toml(&String::from_utf8_lossy(b))),
        )
    }),
    ("batch_manifest", || {
        (
            vec![MANIFEST.to_vec()],
            Box::new(|b: &[u8]| {
                wgslam::fuzz_entry::manifest(
                    Path::new("/fuzz-replay/batch.toml"),
                    &String::from_utf8_lossy(b),
                )
                .map_err(|e| e.to_string())
            }),
        )
    }),
];

const IDENTITY: &[u8] = b"1 0 0 0.5\n0 1 0 0\n0 0 1 -2\n0 0 0 1\n";
const TUM_GT: &[u8] = b"# timestamp tx ty tz qx qy qz qw\n\
1.00 0.1 0.2 0.3 0 0 0 1\n1.03 0.11 0.2 0.3 0 0 0.01 0.99995\n";
const PARAMS: &[u8] = b"profile = \"assignment\"\nicp-dist = 0.08\nfuse-angle = 7\n\
bilateral = true\ndownsample = 4\n";
const MANIFEST: &[u8] = b"output = \"out\"\n[defaults]\nframes = \"1..30\"\ndownsample = 4\n\
[[grid]]\nname = \"g\"\nsequence = [\"a\", \"b\"]\nprofile = [\"robust\", \"assignment\"]\n\
[[job]]\nname = \"one\"\nsequence = \"c\"\nframes = \"0..9\"\n";

/// A reader of the file `file` in a scratch folder: writes the bytes there, then reads.
fn on_file<T: 'static>(name: &str, file: &str, read: fn(&Path) -> wgslam::Result<T>) -> Reader {
    let dir = common::temp_dir(&format!("fuzz-{name}"));
    let path = dir.join(file);
    Box::new(move |b: &[u8]| {
        let _keep = &dir;
        std::fs::write(&path, b).map_err(|e| e.to_string())?;
        read(&path).map(|_| ()).map_err(|e| e.to_string())
    })
}

/// The sequence of `files` (relative paths) with `target`'s bytes replaced, opened in
/// memory, then its first two frames loaded.
fn in_folder(files: Vec<(&'static str, Vec<u8>)>, target: &'static str) -> (Vec<Vec<u8>>, Reader) {
    let seed = files
        .iter()
        .find(|(p, _)| *p == target)
        .expect("target among the files")
        .1
        .clone();
    let read = move |b: &[u8]| {
        let root = PathBuf::from(ROOT);
        let mut held = InMemoryFiles::default();
        for (p, bytes) in &files {
            let bytes = if *p == target {
                b.to_vec()
            } else {
                bytes.clone()
            };
            held.insert(root.join(p), bytes);
        }
        let seq = open_in_memory(&root, held, MAX_TIME_DIFF).map_err(|e| e.to_string())?;
        for i in 0..seq.len().min(2) {
            seq.load(i).map_err(|e| e.to_string())?;
        }
        Ok(())
    };
    (vec![seed], Box::new(read))
}

fn ply_seeds() -> Vec<Vec<u8>> {
    let ascii = b"ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
property float z\nend_header\n0 0 1\n0.5 -0.25 2\n"
        .to_vec();
    let mut binary = b"ply\nformat binary_little_endian 1.0\ncomment c\nelement vertex 2\n\
property float x\nproperty float y\nproperty float z\nend_header\n"
        .to_vec();
    for v in [0.0f32, 0.0, 1.0, 0.5, -0.25, 2.0] {
        binary.extend_from_slice(&v.to_le_bytes());
    }
    vec![ascii, binary]
}

fn pcd_seeds() -> Vec<Vec<u8>> {
    let header = |data: &str| {
        format!(
            "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n\
             WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\nDATA {data}\n"
        )
        .into_bytes()
    };
    let mut ascii = header("ascii");
    ascii.extend_from_slice(b"0 0 1\n0.5 -0.25 2\n");
    let mut binary = header("binary");
    for v in [0.0f32, 0.0, 1.0, 0.5, -0.25, 2.0] {
        binary.extend_from_slice(&v.to_le_bytes());
    }
    vec![ascii, binary]
}

fn kitti_seed() -> Vec<u8> {
    [1.0f32, 2.0, 3.0, 0.5, -4.0, 5.0, 0.25, 0.1]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect()
}

/// A 4x3 16-bit depth PNG.
fn depth_png() -> Vec<u8> {
    let img = image::ImageBuffer::<image::Luma<u16>, _>::from_fn(4, 3, |x, y| {
        image::Luma([5000 + (x * 100 + y * 10) as u16])
    });
    encode(
        image::DynamicImage::ImageLuma16(img),
        image::ImageFormat::Png,
    )
}

/// A 4x3 8-bit colour PNG.
fn rgb_png() -> Vec<u8> {
    let img = image::RgbImage::from_fn(4, 3, |x, y| image::Rgb([x as u8 * 60, y as u8 * 80, 128]));
    encode(image::DynamicImage::ImageRgb8(img), image::ImageFormat::Png)
}

/// A 4x3 JPEG.
fn rgb_jpg() -> Vec<u8> {
    let img = image::RgbImage::from_fn(4, 3, |x, y| image::Rgb([x as u8 * 60, y as u8 * 80, 128]));
    encode(
        image::DynamicImage::ImageRgb8(img),
        image::ImageFormat::Jpeg,
    )
}

fn encode(img: image::DynamicImage, format: image::ImageFormat) -> Vec<u8> {
    let mut out = Cursor::new(Vec::new());
    img.write_to(&mut out, format).expect("encode a seed image");
    out.into_inner()
}

const CAMERA_JSON: &[u8] =
    b"{ \"width\": 4, \"height\": 3, \"fx\": 3.0, \"fy\": 3.0, \"cx\": 1.5, \"cy\": 1.0, \"depth_scale\": 5000.0 }";

/// Two frames of images, as `rgb/0.png` and `depth/0.png` (or `color/` with `.jpg`).
fn images(color_jpg: bool) -> Vec<(&'static str, Vec<u8>)> {
    let color = if color_jpg { rgb_jpg() } else { rgb_png() };
    let names: [&'static str; 2] = if color_jpg {
        ["color/0.jpg", "color/1.jpg"]
    } else {
        ["rgb/0.png", "rgb/1.png"]
    };
    vec![
        ("depth/0.png", depth_png()),
        ("depth/1.png", depth_png()),
        (names[0], color.clone()),
        (names[1], color),
    ]
}

fn icl() -> Vec<(&'static str, Vec<u8>)> {
    let mut f = images(false);
    f.push((
        "associations.txt",
        b"0 depth/0.png 0 rgb/0.png\n1 depth/1.png 1 rgb/1.png\n".to_vec(),
    ));
    f.push(("camera.json", CAMERA_JSON.to_vec()));
    f
}

fn tum() -> Vec<(&'static str, Vec<u8>)> {
    let mut f = images(false);
    f.push((
        "rgb.txt",
        b"# color images\n# timestamp filename\n1.00 rgb/0.png\n1.03 rgb/1.png\n".to_vec(),
    ));
    f.push((
        "depth.txt",
        b"# depth maps\n# timestamp filename\n1.001 depth/0.png\n1.031 depth/1.png\n".to_vec(),
    ));
    f.push(("groundtruth.txt", TUM_GT.to_vec()));
    f.push(("camera.json", CAMERA_JSON.to_vec()));
    f
}

fn eth3d() -> Vec<(&'static str, Vec<u8>)> {
    let mut f = images(false);
    f.push((
        "associated.txt",
        b"1.00 rgb/0.png 1.00 depth/0.png\n1.03 rgb/1.png 1.03 depth/1.png\n".to_vec(),
    ));
    f.push(("calibration.txt", b"3.0 3.0 1.5 1.0\n".to_vec()));
    f.push(("groundtruth.txt", TUM_GT.to_vec()));
    f
}

fn scannet() -> Vec<(&'static str, Vec<u8>)> {
    let mut f = images(true);
    f.push(("pose/0.txt", IDENTITY.to_vec()));
    f.push(("pose/1.txt", IDENTITY.to_vec()));
    let k = b"3 0 1.5 0\n0 3 1 0\n0 0 1 0\n0 0 0 1\n".to_vec();
    f.push(("intrinsic/intrinsic_depth.txt", k.clone()));
    f.push(("intrinsic/intrinsic_color.txt", k));
    f
}
