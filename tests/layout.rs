//! Compares each `#[repr(C)]` struct of `src/layout.rs` with naga's layout of the WGSL
//! struct of the same name in `shaders/common.wgsl`: size, member names, order and offsets.
//! No GPU needed.

use std::mem::{offset_of, size_of};

use wgslam::gpu::shaders;
use wgslam::layout::*;

/// `(struct name, size, [(member, offset)])` for the Rust side.
type RustLayout = (&'static str, usize, Vec<(&'static str, usize)>);

macro_rules! rust_layout {
    ($ty:ident { $($field:ident),* $(,)? }) => {
        (
            stringify!($ty),
            size_of::<$ty>(),
            vec![$((stringify!($field), offset_of!($ty, $field))),*],
        )
    };
}

fn rust_layouts() -> Vec<RustLayout> {
    vec![
        rust_layout!(PreprocessParams {
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            raw_width,
            raw_height,
            stride,
            depth_scale,
            min_depth_m,
            max_depth_m
        }),
        rust_layout!(NormalParams {
            width,
            height,
            max_depth_jump_m,
            _pad
        }),
        rust_layout!(ProjectParams {
            t_world_to_cam,
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            surfel_count,
            _pad
        }),
        rust_layout!(IcpParams {
            t_world_to_cam,
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            dist_threshold_m,
            _pad
        }),
        rust_layout!(FuseParams {
            t_world_to_cam,
            t_cam_to_world,
            fx,
            fy,
            cx,
            cy,
            width,
            height,
            surfel_count,
            frame_id,
            dist_threshold_m,
            cos_normal_threshold,
            capacity,
            _pad
        }),
    ]
}

#[test]
fn rust_and_wgsl_structs_have_the_same_layout() {
    let module = naga::front::wgsl::parse_str(shaders::COMMON).expect("common.wgsl parses");
    let mut layouter = naga::proc::Layouter::default();
    layouter
        .update(module.to_ctx())
        .expect("naga lays out common.wgsl");

    let mut failures = Vec::new();
    for (name, rust_size, rust_members) in rust_layouts() {
        let Some((handle, ty)) = module
            .types
            .iter()
            .find(|(_, t)| t.name.as_deref() == Some(name))
        else {
            failures.push(format!(
                "{name}: no WGSL struct of that name in common.wgsl"
            ));
            continue;
        };
        let naga::TypeInner::Struct { members, span } = &ty.inner else {
            failures.push(format!("{name}: WGSL type is not a struct"));
            continue;
        };
        let wgsl_size = layouter[handle].size as usize;
        if *span as usize != rust_size || wgsl_size != rust_size {
            failures.push(format!(
                "{name}: Rust size {rust_size} bytes, WGSL size {span} (layouter {wgsl_size})"
            ));
        }
        let wgsl_members: Vec<(String, usize)> = members
            .iter()
            .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
            .collect();
        if wgsl_members.len() != rust_members.len() {
            failures.push(format!(
                "{name}: Rust has {} members, WGSL {}",
                rust_members.len(),
                wgsl_members.len()
            ));
        }
        for ((rn, ro), (wn, wo)) in rust_members.iter().zip(&wgsl_members) {
            if rn != wn || *ro != *wo {
                failures.push(format!(
                    "{name}: Rust member `{rn}` at offset {ro}, WGSL member `{wn}` at offset {wo}"
                ));
            }
        }
    }
    assert!(
        failures.is_empty(),
        "layout mismatches:\n{}",
        failures.join("\n")
    );
}

/// The `ICP_SYSTEM_LEN` constant agrees on both sides.
/// The u32 literal value of the constant `name` in common.wgsl.
fn wgsl_u32_const(name: &str) -> u32 {
    let module = naga::front::wgsl::parse_str(shaders::COMMON).expect("common.wgsl parses");
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

#[test]
fn icp_system_len_matches() {
    assert_eq!(wgsl_u32_const("ICP_SYSTEM_LEN") as usize, ICP_SYSTEM_LEN);
}

#[test]
fn map_texture_width_matches() {
    assert_eq!(
        wgsl_u32_const("MAP_TEXTURE_WIDTH"),
        wgslam::layout::MAP_TEXTURE_WIDTH
    );
}
