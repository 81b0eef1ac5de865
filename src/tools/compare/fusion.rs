//! Fusion compared kernel by kernel: the per-pixel buffers of the `fuse` step that no later
//! kernel of the step overwrites, one kernel's output each, in the order of the step's plan.

use serde::Serialize;

use crate::slam::backend::FusionBuffers;
use crate::slam::plan::{Call, FuseCall};

/// Fusion's per-pixel outputs compared kernel by kernel, in the order of the step's plan
/// (`crate::slam::plan::fuse`): the buffers no later kernel of the step overwrites
/// ([`FusionBuffers`]). Reported with a fusion violation, to say which kernel the backends
/// first parted at; it sets no limit of its own.
#[derive(Debug, Clone, Default, Serialize)]
pub struct FusionKernelDiff {
    /// Best-candidate association: pixels where `fuse_select` chose another surfel (or one
    /// backend none); projective: pixels whose `fuse_merge` flag differs.
    pub assoc_pixels: usize,
    /// Largest difference of any component of `fuse_merge_chosen`'s merged surfel per
    /// pixel (best candidate only; metres for positions and radii).
    pub merged_max_abs: f64,
    /// Append slots whose new-surfel flag (`fuse_flags`) differs.
    pub flag_slots: usize,
    /// Append slots whose new-surfel slot (`prefix_sum` over the flags) differs.
    pub offset_slots: usize,
}

impl FusionKernelDiff {
    /// Compares two backends' fusion buffers.
    pub fn of(a: &FusionBuffers, b: &FusionBuffers, best_candidate: bool) -> Self {
        // The surfel a key names (low word), or none (key 0).
        let choice = |k: u64| (k != 0).then_some(k as u32);
        let assoc_pixels = a
            .assoc
            .iter()
            .zip(&b.assoc)
            .filter(|&(&x, &y)| match best_candidate {
                true => choice(x) != choice(y),
                false => (x != 0) != (y != 0),
            })
            .count()
            + a.assoc.len().abs_diff(b.assoc.len());
        let merged_max_abs = match best_candidate && a.merged.len() == b.merged.len() {
            true => a
                .merged
                .iter()
                .zip(&b.merged)
                .flat_map(|(x, y)| x.iter().zip(y).map(|(p, q)| (p - q).abs() as f64))
                .fold(0.0, f64::max),
            false => 0.0,
        };
        let differ = |x: &[u32], y: &[u32]| {
            x.iter().zip(y).filter(|(p, q)| p != q).count() + x.len().abs_diff(y.len())
        };
        FusionKernelDiff {
            assoc_pixels,
            merged_max_abs,
            flag_slots: differ(&a.flags, &b.flags),
            offset_slots: differ(&a.offsets, &b.offsets),
        }
    }

    /// The first kernel, in plan order, whose output differs, and how.
    pub fn first_difference(&self, best_candidate: bool) -> Option<String> {
        let assoc_kernel = match best_candidate {
            true => FuseCall::FuseSelect,
            false => FuseCall::FuseMerge,
        }
        .name();
        if self.assoc_pixels > 0 {
            Some(format!("{assoc_kernel} ({} pixels)", self.assoc_pixels))
        } else if self.merged_max_abs > 0.0 {
            Some(format!(
                "{} (merged surfels up to {:.3e} apart)",
                FuseCall::FuseMergeChosen.name(),
                self.merged_max_abs
            ))
        } else if self.flag_slots > 0 {
            Some(format!(
                "{} ({} slots)",
                FuseCall::FuseFlags.name(),
                self.flag_slots
            ))
        } else if self.offset_slots > 0 {
            Some(format!(
                "{} ({} slots)",
                FuseCall::FuseScan.name(),
                self.offset_slots
            ))
        } else {
            None
        }
    }
}
