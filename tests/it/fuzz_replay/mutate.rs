//! The fixed-seed mutator of the fuzz replay: the library's splitmix64 stream (no
//! dependency, the same corpus on every platform) and the mutations a careless or hostile
//! user's file shows.

use wgslam::seeded::SplitMix;

/// The library's one splitmix64 stream ([`SplitMix`]), counted in `usize`.
pub struct Rng(SplitMix);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(SplitMix::new(seed))
    }

    pub fn next(&mut self) -> u64 {
        self.0.next_u64()
    }

    /// A number in `0..n` (`n > 0`).
    pub fn below(&mut self, n: usize) -> usize {
        self.0.below(n as u64) as usize
    }
}

/// Numbers that break naive readers: huge counts, overflows, negatives, NaN and inf.
const HOSTILE_NUMBERS: &[&str] = &[
    "4294967295",
    "4294967296",
    "18446744073709551616",
    "99999999999999",
    "-1",
    "0",
    "-0",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e309",
    "1e-320",
    "3e38",
    "0x10",
    "",
];

/// Binary values for counts and fields: the largest integers and float specials.
const HOSTILE_WORDS: &[[u8; 4]] = &[
    [0xff, 0xff, 0xff, 0xff],
    [0xff, 0xff, 0xff, 0x7f],
    [0x00, 0x00, 0xc0, 0x7f], // f32 NaN
    [0x00, 0x00, 0x80, 0x7f], // f32 inf
    [0x00, 0x00, 0x00, 0x80], // i32 min
];

/// Most repeats of one line: enough to pass a reader's small limits, small enough to stay
/// fast.
const MAX_REPEATS: usize = 2000;

/// One to three mutations of `seed`.
pub fn mutate(seed: &[u8], rng: &mut Rng) -> Vec<u8> {
    let mut b = seed.to_vec();
    for _ in 0..1 + rng.below(3) {
        mutate_once(&mut b, rng);
    }
    b
}

fn mutate_once(b: &mut Vec<u8>, rng: &mut Rng) {
    match rng.below(10) {
        0 => b.truncate(rng.below(b.len() + 1)),
        1 => {
            for _ in 0..1 + rng.below(8) {
                if !b.is_empty() {
                    let i = rng.below(b.len());
                    b[i] ^= 1 << rng.below(8);
                }
            }
        }
        2 | 3 => replace_number(b, rng),
        4 => repeat_line(b, rng),
        5 => {
            let lines = line_starts(b);
            let i = rng.below(lines.len());
            let end = lines.get(i + 1).copied().unwrap_or(b.len());
            b.drain(lines[i]..end);
        }
        6 => {
            let at = rng.below(b.len() + 1);
            let n = rng.below(16);
            let junk: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            b.splice(at..at, junk);
        }
        7 => {
            if b.len() >= 4 {
                let at = rng.below(b.len() - 3);
                b[at..at + 4].copy_from_slice(&HOSTILE_WORDS[rng.below(HOSTILE_WORDS.len())]);
            }
        }
        8 => {
            let at = rng.below(b.len() + 1);
            let odd: &[u8] = [b"\0".as_slice(), b"\xff\xfe", b"\r", b"\t\t", b"\n\n"][rng.below(5)];
            b.splice(at..at, odd.iter().copied());
        }
        _ => {
            *b = (0..rng.below(256)).map(|_| rng.next() as u8).collect();
        }
    }
}

/// Where each line of `b` starts (at least one: 0).
fn line_starts(b: &[u8]) -> Vec<usize> {
    let mut v = vec![0];
    v.extend(
        b.iter()
            .enumerate()
            .filter(|(i, &c)| c == b'\n' && i + 1 < b.len())
            .map(|(i, _)| i + 1),
    );
    v
}

/// One line of `b`, repeated up to [`MAX_REPEATS`] times in place.
fn repeat_line(b: &mut Vec<u8>, rng: &mut Rng) {
    let lines = line_starts(b);
    let i = rng.below(lines.len());
    let end = lines.get(i + 1).copied().unwrap_or(b.len());
    let line = b[lines[i]..end].to_vec();
    let n = 1 + rng.below(MAX_REPEATS);
    let copies: Vec<u8> = line.iter().copied().cycle().take(line.len() * n).collect();
    b.splice(end..end, copies);
}

/// A number token of `b` (a run of digits, sign, dot and exponent that starts with a digit
/// or a minus), replaced by one of [`HOSTILE_NUMBERS`].
fn replace_number(b: &mut Vec<u8>, rng: &mut Rng) {
    let num = |c: u8| c.is_ascii_digit() || matches!(c, b'.' | b'-' | b'+' | b'e' | b'E');
    let mut tokens = Vec::new();
    let mut i = 0;
    while i < b.len() {
        if (b[i].is_ascii_digit() || b[i] == b'-') && (i == 0 || !b[i - 1].is_ascii_alphanumeric())
        {
            let start = i;
            while i < b.len() && num(b[i]) {
                i += 1;
            }
            tokens.push(start..i);
        } else {
            i += 1;
        }
    }
    if tokens.is_empty() {
        return;
    }
    let t = tokens[rng.below(tokens.len())].clone();
    let with = HOSTILE_NUMBERS[rng.below(HOSTILE_NUMBERS.len())].bytes();
    b.splice(t, with);
}
