//! The surfel map as a structure of arrays on the host (CPU reference and GPU download).
//!
//! One surfel per index `i` across all arrays. Positions and normals are in the world
//! frame. The GPU packs the five arrays into three textures (`gpu::map_textures`) and
//! unpacks them exactly on download.

/// The fused point map: positions, normals, colours, weights, last-updated frames.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelMap {
    /// World-frame position in metres; `w` is unused and kept at 1.
    pub positions: Vec<[f32; 4]>,
    /// World-frame unit normal; `w` is unused and kept at 0.
    pub normals: Vec<[f32; 4]>,
    /// Colour as RGB in 0..255 (float, averaged); `a` is unused and kept at 255.
    pub colors: Vec<[f32; 4]>,
    /// Number of observations fused into the surfel (1 when added).
    pub weights: Vec<f32>,
    /// Sequence position of the frame that last added or merged this surfel.
    pub last_frame: Vec<u32>,
}

impl SurfelMap {
    /// Number of surfels.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when the map holds no surfel.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Appends one surfel.
    pub fn push(&mut self, p: [f32; 3], n: [f32; 3], c: [f32; 3], weight: f32, frame: u32) {
        self.positions.push([p[0], p[1], p[2], 1.0]);
        self.normals.push([n[0], n[1], n[2], 0.0]);
        self.colors.push([c[0], c[1], c[2], 255.0]);
        self.weights.push(weight);
        self.last_frame.push(frame);
    }

    /// Checks that all arrays have the same length (an internal contract).
    pub fn assert_consistent(&self) {
        let n = self.positions.len();
        assert!(
            self.normals.len() == n
                && self.colors.len() == n
                && self.weights.len() == n
                && self.last_frame.len() == n,
            "SurfelMap arrays have different lengths"
        );
    }
}
