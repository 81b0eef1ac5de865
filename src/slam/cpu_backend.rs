//! The CPU reference backend: runs the CPU twins in `cpu/` over host vectors.
//!
//! This is the ground the GPU backend is proven against, so it favours being obviously
//! the same as the shaders over being fast; the map grows as a `Vec` without a capacity cap.

use crate::cpu;
use crate::layout::{
    BilateralParams, CompactParams, FuseParams, IcpParams, NormalParams, PreprocessParams,
    ProjectParams, ICP_SYSTEM_LEN,
};
use crate::slam::map::SurfelMap;
use crate::slam::pipeline::{Backend, FrameMaps};
use crate::Result;

/// Host-side state: the current frame's maps, the prediction and the surfel map.
#[derive(Debug, Default)]
pub struct CpuBackend {
    frame: FrameMaps,
    index_map: Vec<u64>,
    pred_vertex: Vec<[f32; 4]>,
    pred_normal: Vec<[f32; 4]>,
    assoc: Vec<u32>,
    map: SurfelMap,
    /// Compaction's keep flags, offsets and second map, kept between frames (the map and
    /// `spare` swap after each compaction, as the GPU's map textures do).
    flags: Vec<u32>,
    offsets: Vec<u32>,
    spare: SurfelMap,
}

impl CpuBackend {
    /// An empty map.
    pub fn new() -> Self {
        Self::default()
    }

    /// A backend starting from `map` (to resume from a saved map, or to start both backends
    /// from the same map; [`Backend::upload_map`] does the same later).
    pub fn with_map(map: SurfelMap) -> Self {
        map.assert_consistent();
        CpuBackend {
            map,
            ..Self::default()
        }
    }

    /// The map without copying.
    pub fn map(&self) -> &SurfelMap {
        &self.map
    }
}

impl Backend for CpuBackend {
    fn name(&self) -> &'static str {
        "cpu"
    }

    fn preprocess(
        &mut self,
        params: &PreprocessParams,
        bilateral: Option<&BilateralParams>,
        normal: &NormalParams,
        raw_depth: &[u16],
        raw_rgba: &[u32],
    ) -> Result<()> {
        let n = (params.width * params.height) as usize;
        self.frame.vertex.resize(n, cpu::INVALID);
        self.frame.color.resize(n, cpu::INVALID);
        self.frame.normal_depth.resize(n, cpu::INVALID);
        cpu::depth_to_vertex::depth_to_vertex(
            params,
            raw_depth,
            raw_rgba,
            &mut self.frame.vertex,
            &mut self.frame.color,
        );
        // The normals (and through normal_depth, ICP and fusion) see the filtered map when
        // the filter is on; `vertex` stays unfiltered either way.
        let f = &mut self.frame;
        let normals_from = match bilateral {
            Some(b) => {
                f.filtered_vertex.resize(n, cpu::INVALID);
                cpu::bilateral_filter::bilateral_filter(b, &f.vertex, &mut f.filtered_vertex);
                &f.filtered_vertex
            }
            None => {
                f.filtered_vertex.clear();
                &f.vertex
            }
        };
        cpu::vertex_to_normal::vertex_to_normal(normal, normals_from, &mut f.normal_depth);
        Ok(())
    }

    fn predict(&mut self, params: &ProjectParams) -> Result<()> {
        let mut params = *params;
        params.surfel_count = self.map.len() as u32;
        let n = (params.width * params.height) as usize;
        self.index_map.clear();
        self.index_map.resize(n, 0);
        self.pred_vertex.resize(n, cpu::INVALID);
        self.pred_normal.resize(n, cpu::INVALID);
        cpu::project_model::project_model(&params, &self.map.position_weight, &mut self.index_map);
        cpu::predict_model::predict_model(
            &params,
            &self.index_map,
            &self.map.position_weight,
            &self.map.normal_frame,
            &mut self.pred_vertex,
            &mut self.pred_normal,
        );
        Ok(())
    }

    fn icp_system(&mut self, params: &IcpParams) -> Result<[f64; ICP_SYSTEM_LEN]> {
        Ok(cpu::icp_reduce::icp_reduce(
            params,
            &self.pred_vertex,
            &self.pred_normal,
            &self.frame.normal_depth,
        ))
    }

    fn fuse(&mut self, params: &FuseParams) -> Result<usize> {
        let n_pix = (params.width * params.height) as usize;
        let count = self.map.len();
        let mut params = *params;
        params.surfel_count = count as u32;
        params.capacity = (count + n_pix) as u32;
        self.assoc.clear();
        self.assoc.resize(n_pix, 0);
        let m = &mut self.map;
        cpu::fuse_merge::fuse_merge(
            &params,
            &self.frame.normal_depth,
            &self.frame.color,
            &mut m.position_weight,
            &mut m.normal_frame,
            &mut m.color,
            &mut self.assoc,
        );
        // Room for every pixel, as the GPU backend guarantees before its dispatch.
        m.resize(params.capacity as usize);
        let mut counter = count as u32;
        cpu::fuse_add::fuse_add(
            &params,
            &self.frame.normal_depth,
            &self.frame.color,
            &self.assoc,
            &mut counter,
            &mut m.position_weight,
            &mut m.normal_frame,
            &mut m.color,
        );
        let new_len = counter as usize;
        m.resize(new_len);
        Ok(new_len)
    }

    fn compact(&mut self, params: &CompactParams) -> Result<usize> {
        let n = self.map.len();
        let mut params = *params;
        params.surfel_count = n as u32;
        let m = &self.map;
        self.flags.resize(n, 0);
        cpu::compact_flags::compact_flags(
            &params,
            &m.position_weight,
            &m.normal_frame,
            &mut self.flags,
        );
        self.offsets.resize(n, 0);
        let mut counter = 0u32;
        cpu::prefix_sum::prefix_sum(&params, &self.flags, &mut self.offsets, &mut counter);
        // The second map, as large as the first (as on the GPU), cut to the survivors.
        let out = &mut self.spare;
        out.resize(n);
        cpu::compact_scatter::compact_scatter(
            &params,
            &self.flags,
            &self.offsets,
            &m.position_weight,
            &m.normal_frame,
            &m.color,
            &mut out.position_weight,
            &mut out.normal_frame,
            &mut out.color,
        );
        out.resize(counter as usize);
        std::mem::swap(&mut self.map, &mut self.spare);
        Ok(self.map.len())
    }

    fn surfel_count(&self) -> usize {
        self.map.len()
    }

    fn download_map(&mut self) -> Result<SurfelMap> {
        Ok(self.map.clone())
    }

    fn upload_map(&mut self, map: &SurfelMap) -> Result<()> {
        map.assert_consistent();
        self.map.clone_from(map);
        Ok(())
    }

    fn download_frame(&mut self) -> Result<FrameMaps> {
        Ok(self.frame.clone())
    }

    fn download_prediction(&mut self) -> Result<crate::slam::pipeline::Prediction> {
        Ok((self.pred_vertex.clone(), self.pred_normal.clone()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The removal rule on a hand-made map: only unstable surfels (weight below 3) last seen
    /// more than 5 frames before frame 10 go; the survivors keep their order and contents.
    #[test]
    fn compact_removes_old_unstable_surfels_in_order() {
        // (weight, last_frame, removed?)
        let surfels = [
            (1.0, 1, true),   // seen once, 9 frames ago
            (5.0, 1, false),  // stable, however old
            (1.0, 10, false), // seen in this very frame
            (2.9, 5, false),  // unstable but exactly 5 frames old: not more than the limit
            (2.9, 4, true),   // 6 frames old
            (3.0, 0, false),  // weight exactly the stable weight
            (1.0, 2, true),
            (2.0, 9, false),
        ];
        let mut map = SurfelMap::default();
        for (i, &(w, f, _)) in surfels.iter().enumerate() {
            let x = i as f32;
            map.push([x, 1.0, 2.0], [0.0, 0.0, 1.0], [x, 0.0, 0.0], w, f);
        }
        let mut b = CpuBackend::with_map(map.clone());
        let params = CompactParams {
            surfel_count: 0, // filled in by the backend
            frame_id: 10,
            stable_weight: 3.0,
            max_age_frames: 5,
        };
        let kept = b.compact(&params).unwrap();
        let expected: Vec<usize> = (0..surfels.len()).filter(|&i| !surfels[i].2).collect();
        assert_eq!(kept, expected.len());
        let m = b.map();
        assert_eq!(m.len(), expected.len());
        for (slot, &i) in expected.iter().enumerate() {
            assert_eq!(
                m.position_weight[slot], map.position_weight[i],
                "slot {slot}"
            );
            assert_eq!(m.normal_frame[slot], map.normal_frame[i], "slot {slot}");
            assert_eq!(m.color[slot], map.color[i], "slot {slot}");
        }
        // A rule that keeps everything leaves the map as it is; an empty map stays empty.
        let mut b = CpuBackend::with_map(map.clone());
        let keep_all = CompactParams {
            stable_weight: 0.0,
            ..params
        };
        assert_eq!(b.compact(&keep_all).unwrap(), map.len());
        assert_eq!(b.map(), &map);
        assert_eq!(CpuBackend::new().compact(&params).unwrap(), 0);
    }
}
