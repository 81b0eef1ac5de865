//! The integration tests: one test crate (`it`, so one binary linking wgpu instead of one per
//! file), one module per topic, all run by the harness of `common/harness.rs` (libtest-mimic;
//! a test that cannot run here shows as `ignored` with its reason). Each module's
//! `tests()` lists its tests; each is named `MODULE::name`, so `cargo test --test it MODULE`
//! runs one module. `#[test]` does nothing here (`harness = false`); `suite` checks that no
//! file uses it and that every file is a module.

mod common;

mod accuracy;
mod bags;
mod batch;
mod bindings;
mod cli;
mod compare;
mod compare_perturbed;
mod datasets;
mod decode_ahead;
mod end_to_end;
mod eval;
mod fuzz_replay;
mod gpu_parity;
mod gpu_smoke;
mod hostile;
mod inputs;
mod kernel_places;
mod layout;
mod lens;
mod loop_closure;
mod mesh;
mod portable;
mod render;
mod resolution;
mod rgbd;
mod round_trips;
// `wgslam run --rerun` (cargo feature `rerun`): `cargo test --features rerun --test it rerun`.
#[cfg(feature = "rerun")]
mod rerun;
mod scan_gpu;
mod scan_icp;
mod scan_kernels;
mod shaders;
mod suite;
mod tracking_health;

use std::process::ExitCode;

/// The tests of each named module, named `MODULE::name`.
macro_rules! tests_of {
    ($($module:ident),* $(,)?) => {
        vec![$(common::harness::in_module(stringify!($module), $module::tests())),*]
    };
}

fn main() -> ExitCode {
    // The pipeline cache of every GPU test (and of every `wgslam` they start) lives in a
    // folder of this process's own, never the user's: set before any thread starts.
    let cache = std::env::temp_dir().join(format!("wgslam-it-cache-{}", std::process::id()));
    std::env::set_var(wgslam::gpu::pipeline_cache::CACHE_ENV, &cache);
    #[allow(unused_mut)]
    let mut modules = tests_of![
        accuracy,
        bags,
        batch,
        bindings,
        cli,
        compare,
        compare_perturbed,
        datasets,
        decode_ahead,
        end_to_end,
        eval,
        fuzz_replay,
        gpu_parity,
        gpu_smoke,
        hostile,
        inputs,
        kernel_places,
        layout,
        lens,
        loop_closure,
        mesh,
        portable,
        render,
        resolution,
        rgbd,
        round_trips,
        scan_gpu,
        scan_icp,
        scan_kernels,
        shaders,
        suite,
        tracking_health,
    ];
    #[cfg(feature = "rerun")]
    modules.extend(tests_of![rerun]);
    let code = common::harness::run(modules.into_iter().flatten().collect());
    let _ = std::fs::remove_dir_all(&cache);
    code
}
