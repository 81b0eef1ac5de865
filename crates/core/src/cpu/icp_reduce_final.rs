//! CPU twin of `shaders/icp_reduce_final.wgsl`: the second stage of the ICP reduction, the
//! per-workgroup partial systems of `icp_reduce` (or `photo_reduce`) summed into one.
//!
//! [`sum_tree`] is the shader's fixed-shape tree over entries of any float type: entry `k`
//! is the sum of the partials' entry `k` ([`FINAL_THREADS`] strided serial sums, then
//! halved pairwise), one plain add at a time in the shader's order; over f32 it is the GPU
//! stage's reference, bit for bit. The twin in the one call shape, [`icp_reduce_final`],
//! runs it over the CPU's f64 entries: the CPU's reductions write one partial system of
//! f64 sums (see `cpu::icp_reduce`), which the tree gives back unchanged (each entry plus
//! zeros: a sum started from +0.0 is never -0.0), so the CPU backend's systems keep the
//! f64 sums of every row in pixel order. Why the CPU's element is wider than the shader's:
//! `docs/extending.md`, "The one call shape".

use super::binding::twin;
use crate::layout::ICP_SYSTEM_LEN;

/// Threads of each of the shader's workgroups (`FINAL_THREADS` in icp_reduce_final.wgsl),
/// a power of two.
pub const FINAL_THREADS: usize = 64;

/// The shader's tree over entries of type `E` (f32 as on the GPU, f64 on the CPU): entry
/// `k` of `system` the sum of entry `k` of every `ICP_SYSTEM_LEN`-entry partial system of
/// `partials`. Mirrors `main` in icp_reduce_final.wgsl, workgroup by workgroup.
pub fn sum_tree<E>(partials: &[E], system: &mut [E])
where
    E: Copy + Default + std::ops::Add<Output = E>,
{
    let groups = partials.len() / ICP_SYSTEM_LEN;
    // Workgroup k.
    for k in 0..ICP_SYSTEM_LEN {
        // Thread t's strided serial sum.
        let mut sums = [E::default(); FINAL_THREADS];
        for (t, sum) in sums.iter_mut().enumerate() {
            for g in (t..groups).step_by(FINAL_THREADS) {
                *sum = *sum + partials[g * ICP_SYSTEM_LEN + k];
            }
        }
        // The tree: sums[t] += sums[t + s] for s = T / 2, ..., 1.
        let mut s = FINAL_THREADS / 2;
        while s > 0 {
            for t in 0..s {
                sums[t] = sums[t] + sums[t + s];
            }
            s /= 2;
        }
        system[k] = sums[0];
    }
}

twin! {
    /// The partial systems of `partials` summed into `system` by [`sum_tree`], over the
    /// CPU's f64 entries (the shader's are f32). The parameters are the shader's bindings
    /// in `@binding` order, named as there (see the declarations in
    /// `shaders/icp_reduce_final.wgsl` for shapes, units and frames).
    pub fn icp_reduce_final(partials: &[f64], system: &mut [f64]) {
        sum_tree(partials, system);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Integers small enough to be exact in f32 sum to the exact total in any order, so the
    /// tree must give it; and the tree is not the serial order (a sum whose rounding
    /// depends on order gives another value serially).
    #[test]
    fn the_tree_sums_every_partial_once() {
        let groups = 1024;
        let partials: Vec<f32> = (0..groups * ICP_SYSTEM_LEN)
            .map(|i| (i % 97) as f32)
            .collect();
        let mut system = [0.0f32; ICP_SYSTEM_LEN];
        sum_tree(&partials, &mut system);
        for (k, &s) in system.iter().enumerate() {
            let exact: f32 = (0..groups).map(|g| partials[g * ICP_SYSTEM_LEN + k]).sum();
            assert_eq!(s, exact, "entry {k}");
        }
        // One large value among many small ones: serial order loses the small ones
        // added after it, the tree keeps more of them.
        let mut p = vec![0.0f32; groups * ICP_SYSTEM_LEN];
        for g in 0..groups {
            p[g * ICP_SYSTEM_LEN] = if g == 0 { 1.0e8 } else { 1.0 };
        }
        let serial: f32 = (0..groups).map(|g| p[g * ICP_SYSTEM_LEN]).sum();
        let mut tree = [0.0f32; ICP_SYSTEM_LEN];
        sum_tree(&p, &mut tree);
        assert_ne!(tree[0], serial, "the tree is not the serial sum");
    }

    /// The CPU's reductions write one f64 partial system: the twin gives it back bit for
    /// bit (each entry plus +0.0 adds), so the CPU backend's systems are its reductions'
    /// f64 sums. Entries of every sign, the zeros of a system without rows among them.
    #[test]
    fn one_f64_partial_comes_back_unchanged() {
        let partials: Vec<f64> = (0..ICP_SYSTEM_LEN)
            .map(|i| match i % 4 {
                0 => 0.0,
                1 => -1.0 / (i as f64 + 0.3),
                _ => (i as f64).sqrt() * 1.0e-7,
            })
            .collect();
        let mut system = [f64::NAN; ICP_SYSTEM_LEN];
        icp_reduce_final(&mut [
            super::super::binding::Binding::read(&partials),
            super::super::binding::Binding::write(&mut system),
        ]);
        for k in 0..ICP_SYSTEM_LEN {
            assert_eq!(
                system[k].to_bits(),
                partials[k].to_bits(),
                "entry {k}: {} from {}",
                system[k],
                partials[k]
            );
        }
    }
}
