//! Fusion's per-pixel decisions judged where two backends took them differently (lockstep
//! mode: both fused the same map): each backend's decision is recomputed in f64 from its
//! own inputs (its pose as the `FuseParams` matrices it fused at, its `normal_depth` map,
//! the shared map), and is *explained* when every quantity it turned on sits within the
//! rounding WGSL allows of its gate (a knife edge), a *clear flip* (a bug) when one clears
//! its gate by more. Not a map comparison: [`super::diff_surfel_maps_within`] does that.
//!
//! The quantities, as the kernels compute them in f32: the projection `u = fx x / z + cx +
//! 0.5` (which pixel a surfel lands in), and at that pixel the gates of `fuse_select`'s
//! `candidate_off_ray` (best candidate: distance along the pixel's ray against the
//! surfel's own depth gate, `cpu::fuse_depth_gate`, distance off it, normal cosine, then the smallest off-ray distance wins) or `fuse_merge`'s (projective:
//! world-frame distance and normal cosine). The bounds on their f32 error, from the WGSL
//! accuracy table (0.5 ULP for `+ - *`, fused or not; 2.5 ULP for `/`; `sqrt`, `length`,
//! `normalize` inherited, see `crate::cpu::arith`), are the `*_ULPS` constants; an ULP of
//! `x` is at most `|x| 2^-23` ([`f32::EPSILON`]).

use std::collections::HashMap;

use glam::DVec3;
use serde::Serialize;

use crate::layout::map::SurfelMap;
use crate::layout::{FuseParams, GpuMat4};

/// Error of a camera- or world-frame position the kernels compute, in ULPs of the largest
/// magnitude `R` involved (|surfel|, |translations|, |frame point|): `T p` is three
/// products and three adds over terms and partial sums below `2R`, each rounded by at most
/// 0.5 ULP (fused or not): 6 ULP of `R`; the frame point `((u - cx) z / fx, ...)` rebuilt
/// from its texel, one subtraction, one product and one division: 3.5 ULP; moving it to
/// the world (projective association) another 6. 16 in all for a difference `p - q`; 32
/// gives 2x headroom.
pub const POSITION_ULPS: f64 = 32.0;
/// Relative error of a direction-dependent length (`along`, `off_ray`, or `|q - p|`) on
/// top of the positions' error, in ULPs of the length itself: the ray `q / length(q)`
/// (`length`: a 2-ULP dot product and a 4-ULP `sqrt`; the division 2.5), the dot product
/// with it and `length` of the remainder (`crate::cpu::arith`'s allowances): under 16;
/// 32 with headroom.
pub const LENGTH_ULPS: f64 = 32.0;
/// Error of a normal cosine, in ULPs of 1: a unit normal rotated (three products, two adds
/// of terms below 1: 2.5 ULP) and dotted with another (3 products, 2 adds: 2.5 ULP); 16
/// with headroom.
pub const COSINE_ULPS: f64 = 16.0;
/// Error of a projected pixel coordinate from its own operations, in ULPs of `|u| + |cx| +
/// 1`: `fx x` (0.5), `/ z` (2.5), `+ cx` and `+ 0.5` (0.5 each): 4; 8 with headroom. The
/// camera point's error ([`POSITION_ULPS`]) comes on top, through `du/dp`.
pub const PIXEL_ULPS: f64 = 8.0;
/// Error of best-candidate fusion's depth gate for a surfel (`cpu::fuse_depth_gate`), in
/// ULPs of `dist_m`: a difference (0.5), a division (2.5) and a sum (0.5) of
/// terms at most the gate: 3.5; 8 with headroom.
pub const GATE_ULPS: f64 = 8.0;
/// Clear flips allowed per frame: none. Rounding within the table cannot move a quantity
/// across its gate from farther than the bounds above, on any conformant adapter.
pub const CLEAR_FLIPS_MAX: usize = 0;

/// One backend's side of a fusion: the parameters it fused with (pose included), its frame
/// (`normal_depth`: camera-frame unit normal, depth in metres in w) and its association
/// buffer (`FusionBuffers::assoc`).
pub struct FusionSide<'a> {
    pub params: &'a FuseParams,
    pub normal_depth: &'a [[f32; 4]],
    pub assoc: &'a [u64],
}

/// How the pixels whose fusion decision differs were judged.
#[derive(Debug, Clone, Default, Serialize)]
pub struct DecisionCheck {
    /// Pixels whose association differs (the surfel chosen, or merged or not).
    pub differing_pixels: usize,
    /// Of those, pixels where a backend's decision clears a gate (or the choice between
    /// two candidates) by more than rounding allows: bugs.
    pub clear_flips: usize,
    /// The largest margin of a clear flip relative to its gate (or to the nearer
    /// candidate's off-ray distance): a gate 1 % off gives up to 1e-2.
    pub worst_relative_margin: f64,
    /// The first clear flip, in words (pixel, backend, quantity, margin and bound).
    pub first: Option<String>,
}

impl DecisionCheck {
    /// True when at most `max_clear_flips` decisions were clear flips.
    pub fn within(&self, max_clear_flips: usize) -> bool {
        self.clear_flips <= max_clear_flips
    }
}

/// A surfel's standing at a pixel under one backend's inputs: clearly passes every gate,
/// clearly fails one (with what, its margin in metres or cosine, and the gate), or sits
/// within rounding of one.
#[derive(Debug, Clone)]
enum Standing {
    In,
    Out {
        what: &'static str,
        margin: f64,
        bound: f64,
        gate: f64,
    },
    Edge,
}

/// A surfel that may land in a pixel: its standing there and its off-ray distance
/// (metres, best candidate) with that distance's error bound.
#[derive(Debug, Clone)]
struct Candidate {
    surfel: u32,
    standing: Standing,
    off_ray: f64,
    off_ray_err: f64,
}

/// Judges every pixel whose association differs between `a` and `b`, both fused from
/// `map`; `best_candidate`: the association's kind (the buffers' meaning).
pub fn check(
    map: &SurfelMap,
    a: &FusionSide,
    b: &FusionSide,
    best_candidate: bool,
) -> DecisionCheck {
    let choice = |k: u64| (k != 0).then_some(k as u32);
    let differ = |x: u64, y: u64| match best_candidate {
        true => choice(x) != choice(y),
        false => (x != 0) != (y != 0),
    };
    let pixels: Vec<usize> = (0..a.assoc.len().min(b.assoc.len()))
        .filter(|&p| differ(a.assoc[p], b.assoc[p]))
        .collect();
    let mut out = DecisionCheck {
        differing_pixels: pixels.len(),
        ..DecisionCheck::default()
    };
    if pixels.is_empty() {
        return out;
    }
    for (name, side) in [("A", a), ("B", b)] {
        let found = candidates(map, side, &pixels, best_candidate);
        for &pix in &pixels {
            let cands = found.get(&pix).map_or(&[][..], |c| &c[..]);
            let verdict = match best_candidate {
                true => judge_choice(choice(side.assoc[pix]), cands),
                false => judge_merged(side.assoc[pix] != 0, cands),
            };
            if let Some((why, rel)) = verdict {
                out.clear_flips += 1;
                out.worst_relative_margin = out.worst_relative_margin.max(rel);
                if out.first.is_none() {
                    let w = side.params.camera.width as usize;
                    out.first = Some(format!("pixel ({}, {}), {name}: {why}", pix % w, pix / w));
                }
            }
        }
    }
    out
}

/// Best candidate: the chosen surfel must not clearly fail a gate, and no surfel may
/// clearly pass them all clearly nearer the ray. A clear flip's reason and relative margin.
fn judge_choice(chosen: Option<u32>, cands: &[Candidate]) -> Option<(String, f64)> {
    let x = chosen.map(|s| cands.iter().find(|c| c.surfel == s));
    match x {
        Some(None) => {
            return Some((
                format!(
                    "chose surfel {}, which lands clear of this pixel",
                    chosen.unwrap()
                ),
                1.0,
            ))
        }
        Some(Some(c)) => {
            if let Standing::Out {
                what,
                margin,
                bound,
                gate,
            } = c.standing
            {
                return Some((
                    format!(
                        "chose surfel {}, whose {what} misses its gate {gate:.4e} by {:.3e} \
                         (rounding allows {bound:.1e})",
                        c.surfel, -margin
                    ),
                    -margin / gate.abs().max(f64::MIN_POSITIVE),
                ));
            }
        }
        None => {}
    }
    let x = x.flatten();
    cands
        .iter()
        .filter(|y| matches!(y.standing, Standing::In) && Some(y.surfel) != chosen)
        .find_map(|y| match x {
            None => Some((
                format!(
                    "chose none, but surfel {} passes every gate clearly",
                    y.surfel
                ),
                1.0,
            )),
            Some(x) => {
                let gap = x.off_ray - y.off_ray;
                (gap > x.off_ray_err + y.off_ray_err).then(|| {
                    (
                        format!(
                            "chose surfel {} ({:.4e} m off the ray) over surfel {} ({:.4e} m)",
                            x.surfel, x.off_ray, y.surfel, y.off_ray
                        ),
                        gap / x.off_ray.max(f64::MIN_POSITIVE),
                    )
                })
            }
        })
}

/// Projective association: a merged pixel needs a surfel not clearly failing; an unmerged
/// one must have none clearly passing.
fn judge_merged(merged: bool, cands: &[Candidate]) -> Option<(String, f64)> {
    if merged {
        let all_out = cands
            .iter()
            .all(|c| matches!(c.standing, Standing::Out { .. }));
        return all_out.then(|| {
            let worst = cands.iter().find_map(|c| match c.standing {
                Standing::Out {
                    what, margin, gate, ..
                } => Some((c.surfel, what, margin, gate)),
                _ => None,
            });
            match worst {
                Some((s, what, margin, gate)) => (
                    format!(
                        "merged, but surfel {s}'s {what} misses its gate by {:.3e}",
                        -margin
                    ),
                    -margin / gate.abs().max(f64::MIN_POSITIVE),
                ),
                None => ("merged, but no surfel lands in this pixel".into(), 1.0),
            }
        });
    }
    cands
        .iter()
        .find(|c| matches!(c.standing, Standing::In))
        .map(|c| {
            (
                format!(
                    "not merged, but surfel {} passes every gate clearly",
                    c.surfel
                ),
                1.0,
            )
        })
}

/// A `GpuMat4` (column-major) applied in f64 to a point (`w` = 1) or direction (0).
fn apply(t: &GpuMat4, p: DVec3, w: f64) -> DVec3 {
    let c = |k: usize| DVec3::new(t[k][0] as f64, t[k][1] as f64, t[k][2] as f64);
    c(0) * p.x + c(1) * p.y + c(2) * p.z + c(3) * w
}

/// Every surfel of `map` that may land (within rounding) in one of `pixels` under `side`,
/// with its standing there, by pixel.
fn candidates(
    map: &SurfelMap,
    side: &FusionSide,
    pixels: &[usize],
    best_candidate: bool,
) -> HashMap<usize, Vec<Candidate>> {
    let p = side.params;
    let wanted: HashMap<usize, ()> = pixels.iter().map(|&x| (x, ())).collect();
    let translation = |t: &GpuMat4| DVec3::new(t[3][0] as f64, t[3][1] as f64, t[3][2] as f64);
    let t_len = translation(&p.t_world_to_cam)
        .length()
        .max(translation(&p.t_cam_to_world).length());
    let eps = f32::EPSILON as f64;
    let mut found: HashMap<usize, Vec<Candidate>> = HashMap::new();
    for s in 0..map.len() {
        let pw = map.position_weight[s];
        let p_world = DVec3::new(pw[0] as f64, pw[1] as f64, pw[2] as f64);
        let p_cam = apply(&p.t_world_to_cam, p_world, 1.0);
        let r_mag = p_world.length().max(p_cam.length()).max(t_len);
        let e_pos = POSITION_ULPS * eps * r_mag;
        // A surfel within rounding of the camera plane projects nowhere meaningful.
        if p_cam.z <= e_pos {
            continue;
        }
        let axis = |f: f32, c: f32, x: f64| {
            let (f, c) = (f as f64, c as f64);
            let uf = f * x / p_cam.z + c + 0.5;
            let err = f.abs() / p_cam.z * e_pos * (1.0 + (x / p_cam.z).abs())
                + PIXEL_ULPS * eps * (uf.abs() + c.abs() + 1.0);
            ((uf - err).floor(), (uf + err).floor())
        };
        let (u0, u1) = axis(p.camera.fx, p.camera.cx, p_cam.x);
        let (v0, v1) = axis(p.camera.fy, p.camera.cy, p_cam.y);
        let (w, h) = (p.camera.width as f64, p.camera.height as f64);
        if u1 < 0.0 || v1 < 0.0 || u0 >= w || v0 >= h {
            continue;
        }
        let edge = u0 != u1 || v0 != v1;
        for v in v0.max(0.0) as u32..=v1.min(h - 1.0) as u32 {
            for u in u0.max(0.0) as u32..=u1.min(w - 1.0) as u32 {
                let pix = (v * p.camera.width + u) as usize;
                if !wanted.contains_key(&pix) {
                    continue;
                }
                let mut c = gates(map, s, side, [u, v], p_cam, e_pos, best_candidate);
                if edge && !matches!(c.standing, Standing::Out { .. }) {
                    c.standing = Standing::Edge;
                }
                found.entry(pix).or_default().push(c);
            }
        }
    }
    found
}

/// Surfel `s` (camera-frame centre `p_cam`, position error `e_pos` metres) against the
/// gates of pixel `texel` under `side`, in f64.
fn gates(
    map: &SurfelMap,
    s: usize,
    side: &FusionSide,
    texel: [u32; 2],
    p_cam: DVec3,
    e_pos: f64,
    best_candidate: bool,
) -> Candidate {
    let p = side.params;
    let eps = f32::EPSILON as f64;
    let nd = side.normal_depth[(texel[1] * p.camera.width + texel[0]) as usize];
    let mut c = Candidate {
        surfel: s as u32,
        standing: Standing::In,
        off_ray: 0.0,
        off_ray_err: 0.0,
    };
    if nd[3] <= 0.0 {
        // No measurement: the pixel's validity is the backend's own input, so clear.
        c.standing = Standing::Out {
            what: "pixel's measurement",
            margin: -1.0,
            bound: 0.0,
            gate: 1.0,
        };
        return c;
    }
    let z = nd[3] as f64;
    let q = DVec3::new(
        (texel[0] as f64 - p.camera.cx as f64) * z / p.camera.fx as f64,
        (texel[1] as f64 - p.camera.cy as f64) * z / p.camera.fy as f64,
        z,
    );
    let e_pos = e_pos.max(POSITION_ULPS * eps * q.length());
    let n_nd = DVec3::new(nd[0] as f64, nd[1] as f64, nd[2] as f64);
    let n_world = DVec3::from(map.normal(s).map(|x| x as f64));
    let mut gate = |what: &'static str, margin: f64, bound: f64, gate: f64| {
        if margin < -bound {
            if !matches!(c.standing, Standing::Out { .. }) {
                c.standing = Standing::Out {
                    what,
                    margin,
                    bound,
                    gate,
                };
            }
        } else if margin <= bound && matches!(c.standing, Standing::In) {
            c.standing = Standing::Edge;
        }
    };
    let cos_bound = COSINE_ULPS * eps;
    let dist = p.dist_m as f64;
    let cos_gate = p.cos_normal_threshold as f64;
    let (cosine, off_ray) = if best_candidate {
        let ray = q / q.length();
        let d = p_cam - q;
        let along = d.dot(ray);
        let off = (d - ray * along).length();
        let err = 2.0 * e_pos + LENGTH_ULPS * eps * d.length();
        let radius = map.color[s][3] as f64;
        // The surfel's own depth gate, narrowing with its weight (`cpu::fuse_depth_gate`).
        let confident = p.dist_confident_m as f64;
        let weight = (map.position_weight[s][3] as f64).max(1.0);
        let dist = confident + (dist - confident) / weight;
        let gate_err = GATE_ULPS * eps * p.dist_m as f64;
        gate(
            "distance along the ray",
            dist - along.abs(),
            err + gate_err,
            dist,
        );
        gate("distance off the ray", radius - off, err, radius);
        let cosine = apply(&p.t_world_to_cam, n_world, 0.0).dot(n_nd);
        (cosine, Some((off, err)))
    } else {
        let pw = map.position_weight[s];
        let p_world = DVec3::new(pw[0] as f64, pw[1] as f64, pw[2] as f64);
        let q_world = apply(&p.t_cam_to_world, q, 1.0);
        let len = (q_world - p_world).length();
        let err = 2.0 * e_pos + LENGTH_ULPS * eps * len;
        gate("world-frame distance", dist - len, err, dist);
        (n_world.dot(apply(&p.t_cam_to_world, n_nd, 0.0)), None)
    };
    gate("normal cosine", cosine - cos_gate, cos_bound, cos_gate);
    if let Some((off, err)) = off_ray {
        c.off_ray = off;
        c.off_ray_err = err;
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cpu::pack_depth_index;

    /// A 4x4 camera at the world origin (fx = fy = 100 px), best-candidate gates 5 cm and
    /// 20 degrees, and a map of one surfel `along_m` beyond pixel (2, 2)'s measurement (at
    /// 1 m depth) along its ray, facing the camera.
    fn scene(along_m: f64) -> (FuseParams, Vec<[f32; 4]>, SurfelMap) {
        let mut p: FuseParams = bytemuck::Zeroable::zeroed();
        let identity = [
            [1.0, 0.0, 0.0, 0.0],
            [0.0, 1.0, 0.0, 0.0],
            [0.0, 0.0, 1.0, 0.0],
            [0.0, 0.0, 0.0, 1.0],
        ];
        (p.t_world_to_cam, p.t_cam_to_world) = (identity, identity);
        (
            p.camera.fx,
            p.camera.fy,
            p.camera.cx,
            p.camera.cy,
            p.camera.width,
            p.camera.height,
        ) = (100.0, 100.0, 1.5, 1.5, 4, 4);
        p.dist_m = 0.05;
        p.cos_normal_threshold = 20f32.to_radians().cos();
        let mut nd = vec![[0.0f32; 4]; 16];
        nd[2 * 4 + 2] = [0.0, 0.0, -1.0, 1.0];
        let q = DVec3::new(0.005, 0.005, 1.0);
        let s = q + q.normalize() * along_m;
        let map = SurfelMap {
            position_weight: vec![[s.x as f32, s.y as f32, s.z as f32, 1.0]],
            normal_frame: vec![[0.0f32.to_bits(), 0.0f32.to_bits(), (-1.0f32).to_bits(), 0]],
            color: vec![[0.0, 0.0, 0.0, 0.01]],
        };
        (p, nd, map)
    }

    /// Clear flips for A choosing nothing at pixel (2, 2) and B choosing the surfel.
    fn flips(along_m: f64) -> DecisionCheck {
        let (p, nd, map) = scene(along_m);
        let mut assoc_b = vec![0u64; 16];
        assoc_b[2 * 4 + 2] = pack_depth_index(0.0, 0);
        let assoc_a = vec![0u64; 16];
        let a = FusionSide {
            params: &p,
            normal_depth: &nd,
            assoc: &assoc_a,
        };
        let b = FusionSide {
            params: &p,
            normal_depth: &nd,
            assoc: &assoc_b,
        };
        check(&map, &a, &b, true)
    }

    #[test]
    fn a_choice_clear_of_its_gate_is_a_flip_and_a_knife_edge_is_not() {
        // 1 cm beyond the 5 cm depth gate: B's choice is a bug.
        let c = flips(0.06);
        assert_eq!((c.differing_pixels, c.clear_flips), (1, 1), "{c:?}");
        assert!(
            c.first.as_deref().unwrap().contains("B: chose surfel 0"),
            "{c:?}"
        );
        // Within rounding of the gate (0.1 um; the bound is ~8 um at 1 m): either is right.
        let c = flips(0.05 + 1e-7);
        assert_eq!((c.differing_pixels, c.clear_flips), (1, 0), "{c:?}");
        // Clearly inside the gates: A, which chose nothing, is the one in the wrong.
        let c = flips(0.03);
        assert_eq!(c.clear_flips, 1, "{c:?}");
        assert!(
            c.first.as_deref().unwrap().contains("A: chose none"),
            "{c:?}"
        );
    }
}
