//! CPU twin of `shaders/deform_surfels.wgsl`: moves the map with the pose graph after a
//! loop closure. Each surfel blends the world-frame corrections of the two graph nodes
//! nearest its `last_frame` in time (the last node at or before it, the first after it),
//! weighted linearly by frame; before the first node or after the last, that node's
//! correction alone. Positions: the two corrected positions blended; normals: the two
//! rotated normals blended and renormalised.

use super::binding::twin;
use super::chunk_blocks;
use crate::layout::{DeformNode, DeformParams, MapChunk};

/// The first node whose frame is after `frame` (`node_count` when none). Mirrors
/// `node_after` in deform_surfels.wgsl.
#[inline]
pub fn node_after(nodes: &[DeformNode], frame: u32, node_count: u32) -> u32 {
    let (mut lo, mut hi) = (0u32, node_count);
    while lo < hi {
        let mid = (lo + hi) / 2;
        if nodes[mid as usize].frame <= frame {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

fn dot3(a: [f32; 4], p: [f32; 3]) -> f32 {
    a[0] * p[0] + a[1] * p[1] + a[2] * p[2]
}

/// `R p + t` with a node's correction. Mirrors `correct_point`.
#[inline]
pub fn correct_point(node: &DeformNode, p: [f32; 3]) -> [f32; 3] {
    let r = &node.rows;
    [0, 1, 2].map(|i| dot3(r[i], p) + r[i][3])
}

/// `R n` with a node's correction. Mirrors `correct_normal`.
#[inline]
pub fn correct_normal(node: &DeformNode, n: [f32; 3]) -> [f32; 3] {
    let r = &node.rows;
    [0, 1, 2].map(|i| dot3(r[i], n))
}

twin! {
    /// Moves the chunk's surfels with the pose graph's corrections: the parameters are the
    /// shader's bindings in `@binding` order, named as there (see the declarations in
    /// `shaders/deform_surfels.wgsl` for shapes, units and frames).
    pub fn deform_surfels(
        params: &DeformParams,
        chunk: &MapChunk,
        nodes: &[DeformNode],
        position_weight: &mut [[f32; 4]],
        normal_frame: &mut [[u32; 4]],
    ) {
        let p = *params;
        if p.node_count == 0 {
            return;
        }
        let (_, end) = chunk_blocks(chunk, p.surfel_count);
        for i in chunk.base..end {
            let surfel = (i - chunk.base) as usize;
            let pw = position_weight[surfel];
            let nf = normal_frame[surfel];
            let k = node_after(nodes, nf[3], p.node_count);
            let a = &nodes[if k == 0 { 0 } else { k - 1 } as usize];
            let b = &nodes[k.min(p.node_count - 1) as usize];
            let mut w = 0.0f32;
            if k > 0 && k < p.node_count {
                w = (nf[3] - a.frame) as f32 / (b.frame - a.frame) as f32;
            }
            let xyz = [pw[0], pw[1], pw[2]];
            let (pa, pb) = (correct_point(a, xyz), correct_point(b, xyz));
            let position = [0, 1, 2].map(|j| pa[j] * (1.0 - w) + pb[j] * w);
            let n = [nf[0], nf[1], nf[2]].map(f32::from_bits);
            let (na, nb) = (correct_normal(a, n), correct_normal(b, n));
            let blended = [0, 1, 2].map(|j| na[j] * (1.0 - w) + nb[j] * w);
            let len = dot3([blended[0], blended[1], blended[2], 0.0], blended).sqrt();
            let normal = blended.map(|c| c / len);
            position_weight[surfel] = [position[0], position[1], position[2], pw[3]];
            normal_frame[surfel] = [
                normal[0].to_bits(),
                normal[1].to_bits(),
                normal[2].to_bits(),
                nf[3],
            ];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::binding::Binding;
    use super::*;

    fn translation(frame: u32, t: [f32; 3]) -> DeformNode {
        DeformNode {
            frame,
            rows: [
                [1.0, 0.0, 0.0, t[0]],
                [0.0, 1.0, 0.0, t[1]],
                [0.0, 0.0, 1.0, t[2]],
            ],
            ..bytemuck::Zeroable::zeroed()
        }
    }

    #[test]
    fn surfels_blend_their_bracketing_nodes_by_frame() {
        let nodes = [
            translation(10, [0.0, 0.0, 0.0]),
            translation(20, [1.0, 0.0, 0.0]),
        ];
        let frames = [5u32, 10, 15, 20, 30];
        let mut pw: Vec<[f32; 4]> = frames.iter().map(|_| [0.0, 0.0, 0.0, 2.0]).collect();
        let mut nf: Vec<[u32; 4]> = frames
            .iter()
            .map(|&f| [0.0f32.to_bits(), 0.0f32.to_bits(), 1.0f32.to_bits(), f])
            .collect();
        let params = DeformParams {
            surfel_count: frames.len() as u32,
            node_count: 2,
            _pad0: 0,
            _pad1: 0,
        };
        deform_surfels(&mut [
            Binding::of(&params),
            Binding::of(&MapChunk::whole(64)),
            Binding::read(&nodes),
            Binding::write(&mut pw),
            Binding::write(&mut nf),
        ]);
        let x: Vec<f32> = pw.iter().map(|p| p[0]).collect();
        assert_eq!(x, vec![0.0, 0.0, 0.5, 1.0, 1.0]);
        assert!(pw.iter().all(|p| p[3] == 2.0), "weights are kept");
        assert_eq!(nf[2][3], 15, "last_frame is kept");
        assert_eq!(f32::from_bits(nf[2][2]), 1.0);
    }
}
