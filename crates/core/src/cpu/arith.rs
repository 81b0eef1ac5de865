//! The few f32 operations whose result WGSL lets a conformant implementation round
//! differently from the CPU, as the twins call them: exact ([`Arith::Exact`], the default:
//! IEEE-754 round-to-nearest, the bits the twins have always produced) or perturbed
//! ([`Arith::Perturbed`], a test mode: each result moved within what the WGSL spec's
//! "Floating Point Accuracy" table allows, as a GPU may).
//!
//! The allowances (WGSL, f32, finite inputs in the normal range):
//! - `x / y`: 2.5 ULP; perturbed: the correctly rounded quotient moved by up to
//!   [`DIV_ULPS`] (0.5 + 2 <= 2.5 ULP).
//! - `inverseSqrt`: 2 ULP; perturbed: moved by up to [`INVERSE_SQRT_ULPS`] (1 ULP, so the
//!   result stays within 2 of the exact value after the 0.5 of the correct rounding).
//! - `sqrt`: inherited from `1.0 / inverseSqrt(x)`: 2.5 + 2 (amplified by ~1) ULP, so up to
//!   [`SQRT_ULPS`] (4).
//! - `dot`, `length`, `normalize`: inherited from `x[0] * y[0] + x[1] * y[1] + ...`,
//!   `sqrt(dot(x, x))` and `x / length(x)`: each product-and-add may be fused, then the
//!   sqrt and the divisions as above.
//! - `a * b + c` anywhere: may be evaluated as one fused multiply-add (one rounding
//!   instead of two) or not; perturbed: fused or not, by the operands' hash.
//! - Sums of many terms (a workgroup reduction): WGSL fixes no order across invocations;
//!   perturbed: [`accumulate`] sums rows into f32 partials, a row's partial chosen by a
//!   seeded hash of its pixel, and the partials in f64, as a GPU's threads and host do.
//!
//! A perturbation is a pure function of the operands and the seed (the same inputs give the
//! same result, as on one GPU), so a perturbed run is reproducible. The mode is per thread
//! (the CPU backend runs its twins on the caller's thread): [`with`] sets it around a call.
//! [`with_skipped_merges`] is a test-only hook that plants a bug (a merge skipped) for
//! `tools::compare`'s tests to prove it is caught.

use std::cell::Cell;

use glam::Vec3;

/// How the twins' f32 built-ins round.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Arith {
    /// IEEE-754 f32, round to nearest; what the twins always computed.
    #[default]
    Exact,
    /// Each result moved within the WGSL accuracy table, by a hash of the operands and
    /// `seed`.
    Perturbed { seed: u64 },
}

/// Largest perturbation of a quotient, ULP (WGSL: 2.5 ULP, of which 0.5 is rounding).
pub const DIV_ULPS: u32 = 2;
/// Largest perturbation of `inverseSqrt`, ULP (WGSL: 2 ULP).
pub const INVERSE_SQRT_ULPS: u32 = 1;
/// Largest perturbation of `sqrt`, ULP (inherited from `1.0 / inverseSqrt(x)`).
pub const SQRT_ULPS: u32 = 4;
/// f32 partial sums [`accumulate`] spreads a reduction over in the perturbed mode (a GPU
/// sums each thread's rows in f32, then the threads' partials).
pub const PARTIALS: usize = 64;

thread_local! {
    static MODE: Cell<Arith> = const { Cell::new(Arith::Exact) };
    static SKIP_MERGES: Cell<bool> = const { Cell::new(false) };
    static WIDE_DEPTH_GATE: Cell<bool> = const { Cell::new(false) };
    static PARTIAL_SUMS: Cell<Option<Box<[[f32; 64]; PARTIALS]>>> = const { Cell::new(None) };
}

thread_local! {
    /// Set on a thread, never cleared, once it enters a perturbed mode or a planted bug: until
    /// then every helper takes its exact path after one read of this flag instead of reading
    /// the thread's mode, and the perturbed paths live out of line (`*_slow`, cold) so the
    /// exact ones inline into the twins' loops. Measured on the bundled frames (release, CPU
    /// backend, median ms/frame): the thread's mode read inline in every helper made the CPU
    /// backend 40 % slower than before `arith`; a global atomic flag, 16 % (LLVM keeps an
    /// atomic load inside a twin's loop); this plain thread-local, 5 %.
    static ENGAGED_HERE: Cell<bool> = const { Cell::new(false) };
}

/// False while this thread has not left the exact mode (see `ENGAGED_HERE`).
#[inline(always)]
fn engaged() -> bool {
    ENGAGED_HERE.with(|e| e.get())
}

/// True once this thread entered a mode other than exact or a planted bug: the twins then
/// run their invocations in order on this thread (`invocations`), since the mode is per
/// thread and the perturbed sums are sequential.
#[inline]
pub fn engaged_here() -> bool {
    engaged()
}

/// Runs `f` with the twins' arithmetic in `mode` on this thread, then restores the mode.
pub fn with<R>(mode: Arith, f: impl FnOnce() -> R) -> R {
    with_set(&MODE, mode, mode != Arith::Exact, f)
}

/// Runs `f` with the thread's `cell` set to `value` (marking the thread as `engaged` in a
/// non-default mode when asked), then restores the cell's old value.
fn with_set<T: Copy + 'static, R>(
    cell: &'static std::thread::LocalKey<Cell<T>>,
    value: T,
    engaged: bool,
    f: impl FnOnce() -> R,
) -> R {
    if engaged {
        ENGAGED_HERE.with(|e| e.set(true));
    }
    let old = cell.with(|m| m.replace(value));
    let r = f();
    cell.with(|m| m.set(old));
    r
}

/// Test-only hook: runs `f` with a planted bug, `merged_surfel` returning the surfel
/// unchanged (the merge skipped) for one pixel-surfel pair in [`SKIPPED_MERGE_EVERY`] (by
/// a hash of the surfel). Never set outside `tools::compare`'s planted-bug tests.
#[doc(hidden)]
pub fn with_skipped_merges<R>(f: impl FnOnce() -> R) -> R {
    with_set(&SKIP_MERGES, true, true, f)
}

/// Test-only hook: runs `f` with a planted bug, fusion's depth gate (`candidate_off_ray`'s
/// `dist_m`, the distance along the pixel's ray) [`WIDE_GATE_SCALE`] times as wide. Never
/// set outside `tools::compare`'s planted-bug tests.
#[doc(hidden)]
pub fn with_wide_depth_gate<R>(f: impl FnOnce() -> R) -> R {
    with_set(&WIDE_DEPTH_GATE, true, true, f)
}

/// The planted gate's factor: 1 % wide.
pub const WIDE_GATE_SCALE: f32 = 1.01;

/// `dist_m` as the depth gate uses it: as given, or 1 % wide under the planted bug.
#[inline(always)]
pub fn depth_gate(dist_m: f32) -> f32 {
    match engaged() && WIDE_DEPTH_GATE.with(|m| m.get()) {
        true => dist_m * WIDE_GATE_SCALE,
        false => dist_m,
    }
}

/// One merge in this many is skipped under [`with_skipped_merges`].
pub const SKIPPED_MERGE_EVERY: u64 = 16;

/// True when the planted skipped-merge bug drops the merge into the surfel whose
/// position-weight bits are `key`.
#[inline(always)]
pub fn merge_skipped(key: [f32; 4]) -> bool {
    engaged() && merge_skipped_slow(key)
}

/// [`merge_skipped`] once a planted bug may be set.
#[cold]
#[inline(never)]
fn merge_skipped_slow(key: [f32; 4]) -> bool {
    SKIP_MERGES.with(|m| m.get()) && hash(0x5eed, &key.map(f32::to_bits)) % SKIPPED_MERGE_EVERY == 0
}

/// The seed of the perturbed mode, or `None` when exact.
#[inline]
fn seed() -> Option<u64> {
    if !engaged() {
        return None;
    }
    match MODE.with(|m| m.get()) {
        Arith::Exact => None,
        Arith::Perturbed { seed } => Some(seed),
    }
}

/// SplitMix64 over the operands' bits: the perturbation's only source of variety.
fn hash(seed: u64, bits: &[u32]) -> u64 {
    let mut h = seed ^ 0x9e37_79b9_7f4a_7c15;
    for &b in bits {
        h = (h ^ b as u64).wrapping_add(0x9e37_79b9_7f4a_7c15);
        h = (h ^ (h >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        h = (h ^ (h >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        h ^= h >> 31;
    }
    h
}

/// `x` moved by a number of ULP in `-max..=max` chosen by `h` (toward or away from zero;
/// zero, infinities and NaN stay as they are).
fn nudge(x: f32, max: u32, h: u64) -> f32 {
    if x == 0.0 || !x.is_finite() {
        return x;
    }
    let k = (h % (2 * max as u64 + 1)) as i64 - max as i64;
    let magnitude = (x.to_bits() & 0x7fff_ffff) as i64 + k;
    if magnitude <= 0 || magnitude >= 0x7f80_0000 {
        return x;
    }
    f32::from_bits((x.to_bits() & 0x8000_0000) | magnitude as u32)
}

/// `a / b` (WGSL `x / y`).
#[inline(always)]
pub fn div(a: f32, b: f32) -> f32 {
    match engaged() {
        false => a / b,
        true => div_slow(a, b),
    }
}

/// [`div`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn div_slow(a: f32, b: f32) -> f32 {
    match seed() {
        None => a / b,
        Some(s) => nudge(a / b, DIV_ULPS, hash(s ^ 1, &[a.to_bits(), b.to_bits()])),
    }
}

/// `v / s` componentwise (WGSL `vec3 / f32`).
#[inline(always)]
pub fn div3(v: Vec3, s: f32) -> Vec3 {
    match engaged() {
        false => v / s,
        true => div3_slow(v, s),
    }
}

/// [`div3`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn div3_slow(v: Vec3, s: f32) -> Vec3 {
    match seed() {
        None => v / s,
        Some(_) => Vec3::new(div(v.x, s), div(v.y, s), div(v.z, s)),
    }
}

/// `sqrt(x)`.
#[inline(always)]
pub fn sqrt(x: f32) -> f32 {
    match engaged() {
        false => x.sqrt(),
        true => sqrt_slow(x),
    }
}

/// [`sqrt`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn sqrt_slow(x: f32) -> f32 {
    match seed() {
        None => x.sqrt(),
        Some(s) => nudge(x.sqrt(), SQRT_ULPS, hash(s ^ 2, &[x.to_bits()])),
    }
}

/// `inverseSqrt(x)`, computed exactly as `1.0 / x.sqrt()` (the twins' spelling).
#[inline(always)]
pub fn inverse_sqrt(x: f32) -> f32 {
    match engaged() {
        false => 1.0 / x.sqrt(),
        true => inverse_sqrt_slow(x),
    }
}

/// [`inverse_sqrt`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn inverse_sqrt_slow(x: f32) -> f32 {
    match seed() {
        None => 1.0 / x.sqrt(),
        Some(s) => nudge(
            1.0 / x.sqrt(),
            INVERSE_SQRT_ULPS,
            hash(s ^ 3, &[x.to_bits()]),
        ),
    }
}

/// `a * b + c`, fused (one rounding) or not, as WGSL allows either.
#[inline(always)]
pub fn fma_or_mul_add(a: f32, b: f32, c: f32) -> f32 {
    match engaged() {
        false => a * b + c,
        true => fma_or_mul_add_slow(a, b, c),
    }
}

/// [`fma_or_mul_add`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn fma_or_mul_add_slow(a: f32, b: f32, c: f32) -> f32 {
    match seed() {
        Some(s) if hash(s ^ 4, &[a.to_bits(), b.to_bits(), c.to_bits()]) & 1 == 1 => {
            a.mul_add(b, c)
        }
        _ => a * b + c,
    }
}

/// `dot(a, b)` (glam's `x*x' + y*y' + z*z'`; perturbed: each add may be fused).
#[inline(always)]
pub fn dot(a: Vec3, b: Vec3) -> f32 {
    match engaged() {
        false => a.dot(b),
        true => dot_slow(a, b),
    }
}

/// [`dot`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn dot_slow(a: Vec3, b: Vec3) -> f32 {
    match seed() {
        None => a.dot(b),
        Some(_) => fma_or_mul_add(a.z, b.z, fma_or_mul_add(a.y, b.y, a.x * b.x)),
    }
}

/// `length(v)` = `sqrt(dot(v, v))`.
#[inline(always)]
pub fn length(v: Vec3) -> f32 {
    match engaged() {
        false => v.length(),
        true => length_slow(v),
    }
}

/// [`length`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn length_slow(v: Vec3) -> f32 {
    match seed() {
        None => v.length(),
        Some(_) => sqrt(dot(v, v)),
    }
}

/// `normalize(v)` = `v / length(v)`, or zero when the length is zero (the twins'
/// `normalize_or_zero`).
#[inline(always)]
pub fn normalize_or_zero(v: Vec3) -> Vec3 {
    match engaged() {
        false => v.normalize_or_zero(),
        true => normalize_or_zero_slow(v),
    }
}

/// [`normalize_or_zero`] once a mode other than exact was entered (out of line: see `ENGAGED_HERE`).
#[cold]
#[inline(never)]
fn normalize_or_zero_slow(v: Vec3) -> Vec3 {
    match seed() {
        None => v.normalize_or_zero(),
        Some(_) => {
            let len = length(v);
            if len > 0.0 && len.is_finite() {
                div3(v, len)
            } else {
                Vec3::ZERO
            }
        }
    }
}

/// `m * v` for a column-major 4x4 matrix (`cols`) and a point or direction (`w` = 1 or 0),
/// xyz of the result: `c0 x + c1 y + c2 z + c3 w`, each add possibly fused when perturbed.
#[inline]
pub fn mat4_mul(cols: &[[f32; 4]; 4], v: Vec3, w: f32) -> Vec3 {
    let row = |r: usize| {
        let acc = cols[0][r] * v.x;
        let acc = fma_or_mul_add(cols[1][r], v.y, acc);
        let acc = fma_or_mul_add(cols[2][r], v.z, acc);
        fma_or_mul_add(cols[3][r], w, acc)
    };
    Vec3::new(row(0), row(1), row(2))
}

/// True in the perturbed mode (for helpers whose exact path must stay as it was written).
#[inline(always)]
pub fn perturbed() -> bool {
    engaged() && perturbed_slow()
}

/// [`perturbed`] once a mode other than exact was entered.
#[cold]
#[inline(never)]
fn perturbed_slow() -> bool {
    seed().is_some()
}

/// Adds one row's terms to a reduction: exact, `add(sum)` (the twin's own f64 sum, in pixel
/// order); perturbed, the row's terms rounded to f32 and added to one of [`PARTIALS`] f32
/// partial sums (chosen by a seeded hash of `pixel`), `sum` kept equal to the f64 sum of
/// the partials. A reduction starts when `sum` is all zero (the twin's fresh system).
#[inline(always)]
pub fn accumulate<const N: usize>(sum: &mut [f64; N], pixel: u32, add: impl FnOnce(&mut [f64; N])) {
    match engaged() {
        false => add(sum),
        true => accumulate_slow(sum, pixel, add),
    }
}

/// [`accumulate`] once a mode other than exact was entered.
#[cold]
#[inline(never)]
fn accumulate_slow<const N: usize>(
    sum: &mut [f64; N],
    pixel: u32,
    add: impl FnOnce(&mut [f64; N]),
) {
    let Some(s) = seed() else {
        add(sum);
        return;
    };
    assert!(N <= 64, "accumulate: at most 64 entries");
    let mut row = [0.0f64; N];
    add(&mut row);
    let mut partials = PARTIAL_SUMS
        .with(|p| p.take())
        .unwrap_or_else(|| Box::new([[0.0; 64]; PARTIALS]));
    if sum.iter().all(|&x| x == 0.0) {
        partials.iter_mut().for_each(|p| *p = [0.0; 64]);
    }
    let partial = &mut partials[(hash(s ^ 5, &[pixel]) % PARTIALS as u64) as usize];
    for k in 0..N {
        let old = partial[k];
        partial[k] = old + row[k] as f32;
        // Both f32, so their difference is exact in f64: `sum` stays the partials' sum.
        sum[k] += partial[k] as f64 - old as f64;
    }
    PARTIAL_SUMS.with(|p| p.set(Some(partials)));
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Distance of `a` from `b` in ULP of `b`.
    fn ulps(a: f32, b: f32) -> i64 {
        (a.to_bits() as i64 - b.to_bits() as i64).abs()
    }

    #[test]
    fn exact_is_the_plain_f32_expression() {
        let v = Vec3::new(0.3, -1.7, 2.9);
        assert_eq!(div(1.0, 3.0), 1.0 / 3.0);
        assert_eq!(sqrt(2.0), 2.0f32.sqrt());
        assert_eq!(length(v), v.length());
        assert_eq!(normalize_or_zero(v), v.normalize_or_zero());
        assert_eq!(fma_or_mul_add(0.1, 0.2, 0.3), 0.1 * 0.2 + 0.3);
        assert!(!perturbed());
    }

    #[test]
    fn perturbed_stays_within_the_wgsl_table_and_varies() {
        let (mut moved, mut fused) = (0, 0);
        with(Arith::Perturbed { seed: 7 }, || {
            for i in 1..2000u32 {
                let (a, b) = (i as f32 * 0.37 + 0.1, (i % 97) as f32 * 0.11 + 0.5);
                let q = div(a, b);
                assert!(ulps(q, a / b) <= DIV_ULPS as i64);
                assert!(ulps(sqrt(a), a.sqrt()) <= SQRT_ULPS as i64);
                assert!(ulps(inverse_sqrt(a), 1.0 / a.sqrt()) <= INVERSE_SQRT_ULPS as i64);
                moved += (q != a / b) as u32;
                let (x, y, z) = (a * 1e-3, b * 3.3, -a * b * 3e-3);
                fused += (fma_or_mul_add(x, y, z) != x * y + z) as u32;
                // Deterministic: the same operands give the same result.
                assert_eq!(q, div(a, b));
            }
        });
        assert!(moved > 1000, "{moved}");
        assert!(fused > 100, "{fused}");
    }

    #[test]
    fn perturbed_sums_match_the_exact_sum_to_f32_rounding() {
        let rows: Vec<f64> = (0..10_000)
            .map(|i| ((i * 37) % 101) as f64 * 0.013)
            .collect();
        let mut exact = [0.0f64; 1];
        for (i, &r) in rows.iter().enumerate() {
            accumulate(&mut exact, i as u32, |s| s[0] += r);
        }
        let mut perturbed = [0.0f64; 1];
        with(Arith::Perturbed { seed: 3 }, || {
            for (i, &r) in rows.iter().enumerate() {
                accumulate(&mut perturbed, i as u32, |s| s[0] += r);
            }
        });
        let rel = (exact[0] - perturbed[0]).abs() / exact[0];
        assert!(rel > 0.0 && rel < 1e-5, "{rel}");
    }
}
