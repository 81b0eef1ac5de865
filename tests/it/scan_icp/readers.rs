//! The point-cloud readers (PCD, PLY, XYZ text, KITTI .bin, 4x4 matrices) on good input,
//! and on malformed input with errors that name the file, line and problem.

use crate::common;
use std::path::Path;

use common::harness::{plain, Test};
use wgslam::scan::write::{encode_ply_xyz, format_matrix4};
use wgslam::scan::*;
use wgslam::Error;

use super::{known_motion, pose_err, write};

const PCD_HEADER_XYZI: &str = "# .PCD v0.7\nVERSION 0.7\nFIELDS x y z intensity\nSIZE 4 4 4 4\nTYPE F F F F\nCOUNT 1 1 1 1\nWIDTH 3\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 3\n";

fn pcd_ascii_reads_and_drops_nan() {
    let d = common::temp_dir("scan-pcd-ascii");
    let p = write(
        &d,
        "a.pcd",
        format!("{PCD_HEADER_XYZI}DATA ascii\n1 2 3 9\nnan nan nan 0\n4.5 -5 6e-1 1\n").as_bytes(),
    );
    let c = read_pcd(&p).unwrap();
    assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.5, -5.0, 0.6]]);
    assert_eq!(c.stats.records, 3);
    assert_eq!(c.stats.dropped_non_finite, 1);
}

fn pcd_binary_f64_with_extra_fields() {
    let d = common::temp_dir("scan-pcd-f64");
    let mut bytes = b"VERSION 0.7\nFIELDS rgb x y z\nSIZE 4 8 8 8\nTYPE U F F F\nCOUNT 1 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n".to_vec();
    for p in [[1.5f64, -2.0, 3.25], [0.0, 1.0, f64::INFINITY]] {
        bytes.extend_from_slice(&7u32.to_le_bytes());
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let c = read_pcd(&write(&d, "b.pcd", &bytes)).unwrap();
    assert_eq!(c.points, vec![[1.5, -2.0, 3.25]]);
    assert_eq!(c.stats.dropped_non_finite, 1);
}

fn err_text<T: std::fmt::Debug>(r: Result<T, Error>) -> String {
    r.expect_err("malformed input must be an error").to_string()
}

/// What `read` says of `bytes` written to `dir/name` (it must refuse them).
fn read_error<T: std::fmt::Debug>(
    read: fn(&Path) -> Result<T, Error>,
    dir: &Path,
    name: &str,
    bytes: &[u8],
) -> String {
    err_text(read(&write(dir, name, bytes)))
}

fn pcd_malformed_inputs_name_the_problem() {
    let d = common::temp_dir("scan-pcd-bad");
    let e = read_error(
        read_pcd,
        &d,
        "c.pcd",
        format!("{PCD_HEADER_XYZI}DATA binary_compressed\n\0\0\0\0").as_bytes(),
    );
    assert!(e.contains("unsupported") && e.contains("c.pcd"), "{e}");

    // 3 records of 16 bytes promised, 40 bytes present: record 2 is cut at its start.
    let mut bytes = format!("{PCD_HEADER_XYZI}DATA binary\n").into_bytes();
    let start = bytes.len();
    bytes.extend_from_slice(&[0u8; 40]);
    let e = read_error(read_pcd, &d, "t.pcd", &bytes);
    assert!(e.contains(&format!("byte offset {}", start + 32)), "{e}");

    let e = read_error(
        read_pcd,
        &d,
        "n.pcd",
        format!("{PCD_HEADER_XYZI}DATA ascii\n1 2 3 4\n1 two 3 4\n1 2 3 4\n").as_bytes(),
    );
    assert!(e.contains("n.pcd:13") && e.contains("two"), "{e}");

    let e = read_error(
        read_pcd,
        &d,
        "f.pcd",
        b"FIELDS a b c\nSIZE 4 4 4\nTYPE F F F\nPOINTS 1\nDATA ascii\n1 2 3\n",
    );
    assert!(e.contains("x, y, z"), "{e}");

    let e = read_error(
        read_pcd,
        &d,
        "i.pcd",
        b"FIELDS x y z\nSIZE 2 2 2\nTYPE I I I\nPOINTS 1\nDATA ascii\n1 2 3\n",
    );
    assert!(e.contains("float32"), "{e}");

    assert!(matches!(
        read_pcd(&d.join("missing.pcd")),
        Err(Error::Io { .. })
    ));
}

fn ply_ascii_and_binary() {
    let d = common::temp_dir("scan-ply");
    let ascii = b"ply\nformat ascii 1.0\ncomment hi\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n1 2 3 255\n4 5 6 0\n3 0 1 1\n";
    let c = read_ply_xyz(&write(&d, "a.ply", ascii)).unwrap();
    assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);

    let pts = vec![[0.5f32, -1.0, 2.0], [f32::NAN, 0.0, 0.0], [3.0, 4.0, 5.0]];
    let c = read_cloud(&write(&d, "b.ply", &encode_ply_xyz(&pts))).unwrap();
    assert_eq!(c.points, vec![[0.5, -1.0, 2.0], [3.0, 4.0, 5.0]]);
    assert_eq!(c.stats.dropped_non_finite, 1);

    let e = read_error(read_ply_xyz, &d, "be.ply", b"ply\nformat binary_big_endian 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nend_header\n");
    assert!(e.contains("big-endian PLY is not supported"), "{e}");

    let e = read_error(read_ply_xyz, &d, "short.ply", b"ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n1 2 3\n1 2\n");
    assert!(e.contains("short.ply:9"), "{e}");

    let mut trunc = encode_ply_xyz(&pts);
    trunc.truncate(trunc.len() - 5);
    let e = read_error(read_ply_xyz, &d, "trunc.ply", &trunc);
    assert!(
        e.contains("truncated PLY body") && e.contains("offset 177"),
        "{e}"
    );
}

fn xyz_text_reader() {
    let d = common::temp_dir("scan-xyz");
    let p = write(
        &d,
        "a.xyz",
        b"# header comment\n1 2 3\n\n4,5,6,7,8  # trailing comment\n\t7 8 9 extra\ninf 0 0\n",
    );
    let c = read_cloud(&p).unwrap();
    assert_eq!(
        c.points,
        vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0], [7.0, 8.0, 9.0]]
    );
    assert_eq!(c.stats.dropped_non_finite, 1);

    let e = err_text(read_xyz_text(&write(&d, "b.txt", b"1 2 3\n1 2\n")));
    assert!(e.contains("b.txt:2"), "{e}");
    let e = err_text(read_xyz_text(&write(&d, "c.txt", b"1 2 3\n1 2 z\n")));
    assert!(e.contains("c.txt:2") && e.contains("`z`"), "{e}");
}

fn kitti_bin_reader() {
    let d = common::temp_dir("scan-kitti");
    let mut bytes = Vec::new();
    for p in [
        [1.0f32, 2.0, 3.0, 0.5],
        [f32::NAN, 0.0, 0.0, 0.0],
        [4.0, 5.0, 6.0, 1.0],
    ] {
        for c in p {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let c = read_cloud(&write(&d, "a.bin", &bytes)).unwrap();
    assert_eq!(c.points, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
    assert_eq!(c.stats.dropped_non_finite, 1);
    bytes.extend_from_slice(&[1, 2, 3]);
    let e = err_text(read_kitti_bin(&write(&d, "b.bin", &bytes)));
    assert!(
        e.contains("byte offset 48") && e.contains("3 trailing"),
        "{e}"
    );
}

fn matrix4_reader() {
    let d = common::temp_dir("scan-mat");
    let t = known_motion();
    let back = read_matrix4(&write(&d, "t.txt", format_matrix4(&t).as_bytes())).unwrap();
    let (r, p) = pose_err(&back, &t);
    // format_matrix4 prints 9 decimals.
    assert!(r.to_radians() < 1e-8 && p < 1e-8, "{r} {p}");
    let e = err_text(read_matrix4(&write(
        &d,
        "s.txt",
        b"2 0 0 0\n0 1 0 0\n0 0 1 0\n0 0 0 1\n",
    )));
    assert!(e.contains("not a rigid transform"), "{e}");
    let e = err_text(read_matrix4(&write(&d, "n.txt", b"1 0 0\n0 1 0 0\n")));
    assert!(e.contains("16 numbers"), "{e}");
    let e = err_text(read_matrix4(&write(&d, "w.txt", b"1 0 0 0\n0 x 0 0\n")));
    assert!(e.contains("w.txt:2"), "{e}");
}

pub(super) fn tests() -> Vec<Test> {
    vec![
        plain(
            "pcd_ascii_reads_and_drops_nan",
            pcd_ascii_reads_and_drops_nan,
        ),
        plain(
            "pcd_binary_f64_with_extra_fields",
            pcd_binary_f64_with_extra_fields,
        ),
        plain(
            "pcd_malformed_inputs_name_the_problem",
            pcd_malformed_inputs_name_the_problem,
        ),
        plain("ply_ascii_and_binary", ply_ascii_and_binary),
        plain("xyz_text_reader", xyz_text_reader),
        plain("kitti_bin_reader", kitti_bin_reader),
        plain("matrix4_reader", matrix4_reader),
    ]
}
