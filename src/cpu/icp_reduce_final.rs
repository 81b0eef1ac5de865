//! CPU twin of `shaders/icp_reduce_final.wgsl`: the second stage of the GPU's ICP
//! reduction, the per-workgroup partial systems of `icp_reduce` summed into one.
//!
//! The CPU backend does not need it (its `icp_reduce` sums every row into one f64 system
//! directly); it is the GPU stage's reference, bit for bit: entry `k` is the f32 sum of the
//! partials' entry `k` in workgroup order, one add at a time.

use crate::layout::ICP_SYSTEM_LEN;

/// Arguments: the shader's bindings in `@binding` order, named as there; see the
/// declarations in `shaders/icp_reduce_final.wgsl` for shapes, units and frames.
///
/// `system` is returned instead of written: the summed system, f32.
pub fn icp_reduce_final(partials: &[f32]) -> [f32; ICP_SYSTEM_LEN] {
    let groups = partials.len() / ICP_SYSTEM_LEN;
    let mut system = [0.0f32; ICP_SYSTEM_LEN];
    for (k, entry) in system.iter_mut().enumerate() {
        let mut sum = 0.0f32;
        for g in 0..groups {
            sum += partials[g * ICP_SYSTEM_LEN + k];
        }
        *entry = sum;
    }
    system
}
