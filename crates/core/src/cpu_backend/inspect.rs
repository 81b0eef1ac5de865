//! The CPU backend's copies in and out for tools and tests ([`Inspect`]): its map, frame
//! maps, prediction and fusion buffers are already host memory, so each is a clone.

use super::CpuBackend;
use crate::backend::{FrameMaps, FusionBuffers, Inspect, Prediction};
use crate::layout::map::SurfelMap;
use crate::Result;

impl Inspect for CpuBackend {
    fn download_map(&mut self) -> Result<SurfelMap> {
        Ok(self.map.clone())
    }

    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        map.assert_consistent();
        self.map.clone_from(map);
        self.bounds_dirty_from = 0;
        self.fused_view = None;
        Ok(())
    }

    fn download_frame(&mut self) -> Result<FrameMaps> {
        Ok(self.frame.clone())
    }

    fn download_prediction(&mut self, level: usize) -> Result<Prediction> {
        Ok(self.prediction.get(level).cloned().unwrap_or_default())
    }

    fn download_fusion(&mut self) -> Result<FusionBuffers> {
        Ok(FusionBuffers {
            assoc: self.assoc.clone(),
            merged: self.merged.clone(),
            flags: self.add_flags.clone(),
            offsets: self.add_offsets.clone(),
        })
    }
}
