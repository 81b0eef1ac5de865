//! The surfel map on the host, in the GPU's packed representation (CPU reference map and
//! GPU download alike).
//!
//! Three arrays, one entry per surfel `i`, exactly the elements of the three storage arrays
//! of `gpu::map_buffers` (concatenated over its chunks), so upload and download are plain
//! copies and the CPU twins read and write the same packing as the shaders:
//!
//! | array | x, y, z | w |
//! |---|---|---|
//! | `position_weight` | world-frame position, metres | weight: the confidences fused (observations with the assignment's unit confidence) |
//! | `normal_frame` | f32 bits of the unit world-frame normal | last frame |
//! | `color` | RGB 0..255 (float, averaged) | radius, metres (`surfel_radius`, averaged) |
//!
//! Outputs (PLY, renders, comparisons) read it through the accessors, not the packing.

/// The fused point map, packed as the GPU's map arrays (see the module header).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfelMap {
    /// xyz: world-frame position in metres; w: weight (the confidences fused; with the
    /// assignment's unit confidence the observations, 1 when added).
    pub position_weight: Vec<[f32; 4]>,
    /// xyz: f32 bits of the world-frame unit normal; w: sequence position of the frame that
    /// last added or merged the surfel.
    pub normal_frame: Vec<[u32; 4]>,
    /// RGB in 0..255 (float, averaged); `a`: radius in metres (averaged).
    pub color: Vec<[f32; 4]>,
}

impl SurfelMap {
    /// Number of surfels.
    pub fn len(&self) -> usize {
        self.position_weight.len()
    }

    /// True when the map holds no surfel.
    pub fn is_empty(&self) -> bool {
        self.position_weight.is_empty()
    }

    /// World-frame position of surfel `i`, metres.
    pub fn position(&self, i: usize) -> [f32; 3] {
        let p = self.position_weight[i];
        [p[0], p[1], p[2]]
    }

    /// World-frame unit normal of surfel `i`.
    pub fn normal(&self, i: usize) -> [f32; 3] {
        let n = self.normal_frame[i];
        [n[0], n[1], n[2]].map(f32::from_bits)
    }

    /// Weight of surfel `i`: its confidences summed (observations with unit confidence).
    pub fn weight(&self, i: usize) -> f32 {
        self.position_weight[i][3]
    }

    /// Sequence position of the frame that last added or merged surfel `i`.
    pub fn last_frame(&self, i: usize) -> u32 {
        self.normal_frame[i][3]
    }

    /// Radius of surfel `i`'s disc, metres.
    pub fn radius(&self, i: usize) -> f32 {
        self.color[i][3]
    }

    /// Colour of surfel `i`, RGB 0..255.
    pub fn color(&self, i: usize) -> [f32; 3] {
        let c = self.color[i];
        [c[0], c[1], c[2]]
    }

    /// Appends one surfel: position `p` (metres) and unit normal `n`, world frame; colour
    /// `c` RGB 0..255; radius 0 (unknown: such a surfel covers no pixel's ray in
    /// best-candidate fusion, but merges in projective fusion).
    pub fn push(&mut self, p: [f32; 3], n: [f32; 3], c: [f32; 3], weight: f32, frame: u32) {
        self.position_weight.push([p[0], p[1], p[2], weight]);
        self.normal_frame
            .push([n[0].to_bits(), n[1].to_bits(), n[2].to_bits(), frame]);
        self.color.push([c[0], c[1], c[2], 0.0]);
    }

    /// Resizes every array to `n` surfels (new slots zero).
    pub fn resize(&mut self, n: usize) {
        self.position_weight.resize(n, [0.0; 4]);
        self.normal_frame.resize(n, [0; 4]);
        self.color.resize(n, [0.0; 4]);
    }

    /// Checks that all arrays have the same length (an internal contract).
    pub fn assert_consistent(&self) {
        let n = self.position_weight.len();
        assert!(
            self.normal_frame.len() == n && self.color.len() == n,
            "SurfelMap arrays have different lengths"
        );
    }
}
