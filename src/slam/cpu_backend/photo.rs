//! The CPU backend's photometric system (`photo_reduce` over the level-0 prediction and
//! frame maps), for [`crate::slam::backend::Backend::rgbd_system`]; beside the step
//! implementations only to keep that file short.

use super::CpuBackend;
use crate::cpu;
use crate::layout::{IcpParams, ICP_SYSTEM_LEN};

impl CpuBackend {
    /// `photo_reduce` at `params` over level 0 (after `icp_system(0, ..)` checked that a
    /// prediction exists): the summed 29-entry photometric system.
    pub(super) fn photo_system(&self, params: &IcpParams) -> [f64; ICP_SYSTEM_LEN] {
        let (pred_vertex, _) = &self.prediction[0];
        cpu::photo_reduce::photo_reduce(
            params,
            pred_vertex,
            &self.pred_intensity,
            &self.frame.normal_depth,
            &self.frame.color,
        )
    }
}
