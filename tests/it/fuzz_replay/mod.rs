//! Seeded fuzz replay (issue 46 item 3): every reader of user files is fed small valid
//! examples and fixed-seed mutations of them (truncations, byte flips, hostile numbers
//! such as huge counts, NaN and inf, repeated and dropped lines, random bytes). Each must
//! return `Ok` or an `Err` with a message, never panic. The seed is fixed, so CI replays
//! the same corpus every run; a failure names the reader, the seed file and the case.
//! Each crash the fuzzing found is also a named regression case below.

use std::panic::{catch_unwind, AssertUnwindSafe};

use crate::common;
use common::harness::{plain, Test};

mod mutate;
mod readers;

use mutate::Rng;

/// Mutated inputs per seed file and reader: about 20 readers times a few seeds times this
/// stays within a few seconds in a debug build.
const CASES_PER_SEED: u64 = 400;

/// The pass's fixed seed: each case's own seed derives from it, the reader's name, the
/// seed file's index and the case number, so every case replays alone.
const BASE_SEED: u64 = 0x46_46_46;

pub fn tests() -> Vec<Test> {
    readers::CASES
        .iter()
        .map(|&(name, make)| {
            plain(name, move || {
                let (seeds, read) = make();
                replay(name, &seeds, read)
            })
        })
        .chain([plain(
            "regression_pcd_coordinate_count_0",
            pcd_coordinate_count_0,
        )])
        .collect()
}

/// The seed of case `case` of seed file `file` for `reader`.
fn case_seed(reader: &str, file: usize, case: u64) -> u64 {
    let name = reader.bytes().fold(0xcbf2_9ce4_8422_2325_u64, |h, b| {
        (h ^ b as u64).wrapping_mul(0x100_0000_01b3)
    });
    BASE_SEED ^ name ^ ((file as u64) << 40) ^ case
}

/// A reader under test: bytes in, `Ok` or an error's message out.
pub type Reader = Box<dyn Fn(&[u8]) -> Result<(), String>>;

/// Runs `read` on each seed (which must read `Ok`) and on [`CASES_PER_SEED`] mutations of
/// it; a panic, or an error with an empty message, fails the test naming each such case.
fn replay(reader: &str, seeds: &[Vec<u8>], read: Reader) {
    let mut failures = Vec::new();
    for (file, seed) in seeds.iter().enumerate() {
        if let Err(e) = read(seed) {
            failures.push(format!("{reader}: seed file {file} is not read Ok: {e}"));
        }
        for case in 1..=CASES_PER_SEED {
            let s = case_seed(reader, file, case);
            let bytes = mutate::mutate(seed, &mut Rng::new(s));
            match catch_unwind(AssertUnwindSafe(|| read(&bytes))) {
                Ok(Ok(())) => {}
                Ok(Err(e)) if !e.trim().is_empty() => {}
                Ok(Err(_)) => failures.push(format!(
                    "{reader}: seed file {file} case {case} (seed {s:#x}): an empty error"
                )),
                Err(p) => failures.push(format!(
                    "{reader}: seed file {file} case {case} (seed {s:#x}) panicked: {}; input {:?}",
                    panic_text(&p),
                    String::from_utf8_lossy(&bytes[..bytes.len().min(300)])
                )),
            }
        }
    }
    assert!(failures.is_empty(), "{}", failures.join("\n"));
}

fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<String>()
        .cloned()
        .or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_else(|| "(no message)".into())
}

/// Found by `cloud_by_extension` (issue 46): a binary PCD whose `z` has `COUNT 0` indexed an
/// empty record and panicked; it is now an error naming the field.
fn pcd_coordinate_count_0() {
    let dir = common::temp_dir("fuzz-regression-pcd-count-0");
    let path = dir.join("c.pcd");
    let mut bytes = b"VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 0\n\
WIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA binary\n"
        .to_vec();
    bytes.extend_from_slice(&[0u8; 16]);
    std::fs::write(&path, bytes).unwrap();
    let err = wgslam::scan::read::read_cloud(&path)
        .unwrap_err()
        .to_string();
    assert!(err.contains("`z` has COUNT 0"), "{err}");
}
