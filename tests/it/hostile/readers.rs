//! Hostile inputs: Readers and sizes with bounds: declared sizes checked against the file, special files refused.

use super::*;

// ---- 4. readers and sizes with bounds -------------------------------------------------

/// A PCD header with `fields`/`sizes`/`types`, `points` and `data` kind, then `body`.
fn pcd(path: &Path, fields: &str, sizes: &str, types: &str, points: &str, data: &str, body: &[u8]) {
    let counts = vec!["1"; fields.split_whitespace().count()].join(" ");
    let mut bytes = format!(
        "VERSION 0.7\nFIELDS {fields}\nSIZE {sizes}\nTYPE {types}\nCOUNT {counts}\nWIDTH 1\n\
         HEIGHT 1\nPOINTS {points}\nDATA {data}\n"
    )
    .into_bytes();
    bytes.extend_from_slice(body);
    std::fs::write(path, bytes).unwrap();
}

/// `wgslam register FILE OTHER` fails with a clear error (exit status 1: no panic, no
/// abort) that contains `want`, within seconds.
fn refused(file: &Path, other: &Path, want: &str) {
    let t0 = std::time::Instant::now();
    let o = wgslam(&["register", s(file), s(other)]);
    assert_eq!(o.status.code(), Some(1), "{}: {}", file.display(), text(&o));
    assert!(text(&o).contains(want), "{}: {}", file.display(), text(&o));
    assert!(!text(&o).contains("panicked"), "{}", text(&o));
    assert!(
        t0.elapsed().as_secs() < 20,
        "{}: took {:?}",
        file.display(),
        t0.elapsed()
    );
}

fn cloud_readers_check_declared_sizes_against_the_file() {
    let dir = common::temp_dir("hostile-readers");
    let other = dir.join("other.xyz");
    std::fs::write(&other, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    let f = |n: &str| dir.join(n);
    // PCD: 10^12 ascii points (was an allocation abort), 2^62 binary points (a panic,
    // "capacity overflow"), SIZE 2^64-1 on a skipped field (an index panic).
    pcd(
        &f("a.pcd"),
        "x y z",
        "4 4 4",
        "F F F",
        "1000000000000",
        "ascii",
        b"1 2 3\n",
    );
    refused(&f("a.pcd"), &other, "promises 1000000000000 points");
    pcd(
        &f("b.pcd"),
        "x y z",
        "4 4 4",
        "F F F",
        "4611686018427387904",
        "binary",
        &[0; 24],
    );
    refused(&f("b.pcd"), &other, "truncated");
    pcd(
        &f("c.pcd"),
        "x y z w",
        "4 4 4 18446744073709551615",
        "F F F U",
        "1",
        "binary",
        &[0; 24],
    );
    refused(&f("c.pcd"), &other, "SIZE 18446744073709551615");
    // PLY: 10^9 vertices of 2003 properties (a 268 GB reservation), 10^18 records of an
    // element before the vertices (a 50-year skip loop), binary and ASCII.
    let props: String = (0..2000)
        .map(|i| format!("property float p{i}\n"))
        .collect();
    let mut v = format!(
        "ply\nformat binary_little_endian 1.0\nelement vertex 1000000000\nproperty float x\n\
         property float y\nproperty float z\n{props}end_header\n"
    )
    .into_bytes();
    v.extend_from_slice(&[0; 64]);
    std::fs::write(f("a.ply"), v).unwrap();
    refused(&f("a.ply"), &other, "truncated PLY body");
    for (name, format, prop) in [
        ("b.ply", "binary_little_endian", "property uchar a"),
        ("c.ply", "binary_little_endian", "property list uchar int i"),
        ("d.ply", "ascii", "property uchar a"),
    ] {
        let mut v = format!(
            "ply\nformat {format} 1.0\nelement junk 1000000000000000000\n{prop}\n\
             element junk2 18446744073709551615\n{prop}\nelement vertex 1\nproperty float x\n\
             property float y\nproperty float z\nend_header\n"
        )
        .into_bytes();
        v.extend_from_slice(b"1\n2\n3 4 5\n");
        std::fs::write(f(name), v).unwrap();
        refused(&f(name), &other, "truncated PLY body");
    }
}

fn special_and_oversized_files_are_refused() {
    let dir = common::temp_dir("hostile-special");
    let other = dir.join("other.xyz");
    std::fs::write(&other, "0 0 0\n1 0 0\n0 1 0\n").unwrap();
    // /dev/zero grew until out of memory; a FIFO blocked forever.
    for args in [
        vec!["eval", "/dev/zero", "/dev/zero"],
        vec!["register", "/dev/zero", s(&other)],
    ] {
        let o = wgslam(&args);
        assert_eq!(o.status.code(), Some(1), "{}", text(&o));
        assert!(text(&o).contains("not a regular file"), "{}", text(&o));
    }
    #[cfg(unix)]
    {
        let fifo = dir.join("fifo.txt");
        let made = Command::new("mkfifo").arg(&fifo).status().unwrap();
        assert!(made.success());
        for args in [
            vec!["eval", s(&fifo), s(&fifo)],
            vec!["register", s(&fifo), s(&other)],
        ] {
            let o = wgslam(&args);
            assert_eq!(o.status.code(), Some(1), "{}", text(&o));
            assert!(text(&o).contains("not a regular file"), "{}", text(&o));
        }
    }
    let o = wgslam(&["eval", s(&dir), s(&dir)]);
    assert!(text(&o).contains("is a folder"), "{}", text(&o));
    // Past the documented input limit (lowered here through its variable).
    let big = dir.join("big.txt");
    std::fs::write(&big, vec![b'#'; 4096]).unwrap();
    let o = wgslam_env(
        &["eval", s(&big), s(&big)],
        &[("WGSLAM_MAX_INPUT_BYTES", "1000")],
    );
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(text(&o).contains("WGSLAM_MAX_INPUT_BYTES"), "{}", text(&o));
}

fn revisit_and_grid_sizes_are_bounded() {
    let dir = common::temp_dir("hostile-limits");
    let t0 = std::time::Instant::now();
    let o = wgslam(&[
        "run",
        "--revisit",
        "100000000000",
        "--out",
        s(&dir.join("o")),
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("WGSLAM_MAX_REVISIT_FRAMES"),
        "{}",
        text(&o)
    );
    // A 10-override grid of 4 values: 4^10 jobs (batch list ran for over 10 minutes).
    let overrides: Vec<String> = [
        "icp-dist",
        "icp-huber",
        "icp-angle",
        "fuse-dist",
        "fuse-angle",
        "max-depth",
        "min-depth",
        "icp-iters",
        "bilateral-sigma-space",
        "bilateral-sigma-depth",
    ]
    .iter()
    .map(|k| format!("{k} = [1, 2, 3, 4]"))
    .collect();
    let m = dir.join("grid.toml");
    std::fs::write(
        &m,
        format!(
            "output = \"o\"\n[[grid]]\nsequence = \"s\"\noverrides = {{ {} }}\n",
            overrides.join(", ")
        ),
    )
    .unwrap();
    let o = wgslam(&["batch", "list", s(&m)]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    assert!(
        text(&o).contains("1048576 jobs") && text(&o).contains("WGSLAM_MAX_JOBS"),
        "{}",
        text(&o)
    );
    assert!(t0.elapsed().as_secs() < 20, "took {:?}", t0.elapsed());
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "cloud_readers_check_declared_sizes_against_the_file",
            cloud_readers_check_declared_sizes_against_the_file,
        ),
        plain(
            "special_and_oversized_files_are_refused",
            special_and_oversized_files_are_refused,
        ),
        plain(
            "revisit_and_grid_sizes_are_bounded",
            revisit_and_grid_sizes_are_bounded,
        ),
    ]
}
