//! Compares each `#[repr(C)]` struct of `crates/core/src/layout/mod.rs` with naga's layout of the WGSL
//! struct of the same name in `shaders/common.wgsl`: size, member names, order and offsets,
//! and the struct of each nested member (`camera: Camera`, whose own fields the `Camera`
//! entry checks) (through `tests/it/common/wgsl.rs`), and the constants shared by both
//! sides. No GPU needed.

use crate::common;

use common::harness::plain;
use common::wgsl::{self, rust_layout, RustLayout};
use wgslam::gpu::shaders;
use wgslam::layout::*;

fn rust_layouts() -> Vec<RustLayout> {
    vec![
        rust_layout!(Camera {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            _pad0,
            _pad1
        }),
        rust_layout!(PreprocessParams {
            camera: Camera,
            raw_width,
            raw_height,
            stride,
            depth_scale,
            min_depth_m,
            max_depth_m,
            _pad0,
            _pad1
        }),
        rust_layout!(BilateralParams {
            camera: Camera,
            radius_px,
            sigma_space_px,
            sigma_depth_m,
            sigma_depth_per_m2,
            filter_points,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(NormalParams {
            width,
            height,
            max_depth_jump_m,
            _pad
        }),
        rust_layout!(FernParams {
            width,
            height,
            cell_width,
            cell_height,
            fern_count,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(DeformParams {
            surfel_count,
            node_count,
            _pad0,
            _pad1
        }),
        rust_layout!(DeformNode {
            frame,
            _pad0,
            _pad1,
            _pad2,
            rows
        }),
        rust_layout!(Fern {
            cell_u,
            cell_v,
            _pad0,
            _pad1,
            threshold
        }),
        rust_layout!(PyramidParams {
            camera: Camera,
            fine_width,
            fine_height,
            radius_px,
            max_depth_diff_m,
            max_depth_diff_per_m2,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(ProjectParams {
            t_world_to_cam,
            camera: Camera,
            surfel_count,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(IcpParams {
            t_world_to_cam,
            camera: Camera,
            dist_m,
            cos_normal_threshold,
            huber_m,
            noise_weighting,
            photo_depth_gate_m,
            photo_huber,
            photo_gradient_min,
            photo_source_step,
            photo_source_width,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(IntensityParams {
            width,
            height,
            fine_width,
            fine_height,
            level,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(FuseParams {
            t_world_to_cam,
            t_cam_to_world,
            camera: Camera,
            surfel_count,
            frame_id,
            dist_m,
            cos_normal_threshold,
            capacity,
            association,
            confidence_sigma,
            prune_scale,
            dist_confident_m,
            _pad0,
            _pad1,
            _pad2
        }),
        rust_layout!(CompactParams {
            surfel_count,
            frame_id,
            stable_weight,
            max_age_frames
        }),
        rust_layout!(MapChunk {
            base,
            slots,
            _pad0,
            _pad1
        }),
        rust_layout!(BoundsParams {
            surfel_count,
            block_from,
            _pad0,
            _pad1
        }),
    ]
}

fn rust_and_wgsl_structs_have_the_same_layout() {
    let module = wgsl::parse("shaders/common.wgsl", shaders::COMMON);
    let failures: Vec<String> = rust_layouts()
        .iter()
        .flat_map(|rust| wgsl::layout_mismatches("common.wgsl", &module, rust))
        .collect();
    assert!(
        failures.is_empty(),
        "layout mismatches:\n{}",
        failures.join("\n")
    );
}

/// The u32 literal value of the constant `name` in common.wgsl.
fn wgsl_u32_const(name: &str) -> u32 {
    let module = wgsl::parse("shaders/common.wgsl", shaders::COMMON);
    let (_, c) = module
        .constants
        .iter()
        .find(|(_, c)| c.name.as_deref() == Some(name))
        .unwrap_or_else(|| panic!("common.wgsl declares {name}"));
    match module.global_expressions[c.init] {
        naga::Expression::Literal(naga::Literal::U32(v)) => v,
        ref e => panic!("{name} is not a u32 literal: {e:?}"),
    }
}

/// The 29-float system's length and the indices of its parts agree on both sides.
fn icp_system_len_matches() {
    assert_eq!(wgsl_u32_const("ICP_SYSTEM_LEN") as usize, ICP_SYSTEM_LEN);
    for (name, rust) in [
        ("ICP_ATB_OFFSET", wgslam::layout::ICP_ATB_OFFSET),
        ("ICP_COUNT_INDEX", wgslam::layout::ICP_COUNT_INDEX),
        ("ICP_RESIDUAL_INDEX", wgslam::layout::ICP_RESIDUAL_INDEX),
    ] {
        assert_eq!(wgsl_u32_const(name) as usize, rust, "{name}");
    }
    // 21 of AᵀA, then 6 of Aᵀb, the count and the squared residuals, nothing left over.
    assert_eq!(wgslam::layout::ICP_ATB_OFFSET, 21);
    assert_eq!(wgslam::layout::ICP_COUNT_INDEX, 21 + 6);
    assert_eq!(wgslam::layout::ICP_RESIDUAL_INDEX + 1, ICP_SYSTEM_LEN);
}

/// The culling block size agrees on both sides, and chunks of whole blocks fit it; so does
/// the fern code of a cell without depth.
fn block_surfels_matches() {
    assert_eq!(wgsl_u32_const("FERN_NO_DEPTH"), FERN_NO_DEPTH);
    assert_eq!(wgsl_u32_const("BLOCK_SURFELS"), BLOCK_SURFELS);
    assert_eq!(
        wgslam::gpu::map_buffers::DEFAULT_CHUNK_SURFELS % BLOCK_SURFELS as usize,
        0
    );
}

/// The ordered encoding of the block boxes keeps the float order (negative, zero, positive,
/// infinities) and round-trips exactly, so integer atomicMin/atomicMax grow boxes right.
fn ordered_encoding_keeps_float_order() {
    let xs = [
        f32::NEG_INFINITY,
        -1.0e30,
        -3.5,
        -1.0,
        -1.0e-30,
        -0.0,
        0.0,
        1.0e-30,
        0.25,
        1.0,
        7.0,
        1.0e30,
        f32::INFINITY,
    ];
    for w in xs.windows(2) {
        let (a, b) = (ordered_from_f32(w[0]), ordered_from_f32(w[1]));
        assert!(a <= b, "{} -> {a:#x} vs {} -> {b:#x}", w[0], w[1]);
    }
    for &x in &xs {
        assert_eq!(f32_from_ordered(ordered_from_f32(x)).to_bits(), x.to_bits());
    }
}

/// Append order (`cpu::append_index`, the order `fuse_add` appends new surfels in) has the
/// same tile size on both sides, sends every pixel of an image to its own entry below
/// `append_slots`, and makes compact blocks: when every pixel of a 640 x 480 frame is new,
/// each run of `BLOCK_SURFELS` consecutive surfels comes from one 32 x 32 pixel square.
fn append_order_is_a_compact_bijection() {
    assert_eq!(wgsl_u32_const("APPEND_TILE_PX"), APPEND_TILE_PX);
    for (w, h) in [(640, 480), (320, 240), (160, 120), (17, 9), (1, 1)] {
        let slots = append_slots(w, h);
        let mut owner = vec![None; slots];
        for v in 0..h {
            for u in 0..w {
                let a = wgslam::cpu::append_index([u, v]);
                assert!(a < slots, "{w}x{h}: pixel ({u}, {v}) at {a} of {slots}");
                assert_eq!(owner[a], None, "{w}x{h}: ({u}, {v}) shares entry {a}");
                owner[a] = Some((u, v));
            }
        }
        // The holes (tiles outside the image) cost at most 2x the pixels at these sizes.
        assert!(slots <= 2 * (w * h) as usize + (APPEND_TILE_PX * APPEND_TILE_PX) as usize * 4);
        if (w, h) == (640, 480) {
            let pixels: Vec<(u32, u32)> = owner.iter().flatten().copied().collect();
            for block in pixels.chunks(BLOCK_SURFELS as usize) {
                let (u0, u1) = (
                    block.iter().map(|p| p.0).min(),
                    block.iter().map(|p| p.0).max(),
                );
                let (v0, v1) = (
                    block.iter().map(|p| p.1).min(),
                    block.iter().map(|p| p.1).max(),
                );
                let span = (u1.unwrap() - u0.unwrap() + 1, v1.unwrap() - v0.unwrap() + 1);
                assert_eq!(
                    span,
                    (32, 32),
                    "a block of a new frame spans {span:?} pixels"
                );
            }
        }
    }
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "rust_and_wgsl_structs_have_the_same_layout",
            rust_and_wgsl_structs_have_the_same_layout,
        ),
        plain("icp_system_len_matches", icp_system_len_matches),
        plain("block_surfels_matches", block_surfels_matches),
        plain(
            "append_order_is_a_compact_bijection",
            append_order_is_a_compact_bijection,
        ),
        plain(
            "ordered_encoding_keeps_float_order",
            ordered_encoding_keeps_float_order,
        ),
    ]
}
