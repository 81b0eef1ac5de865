//! GPU infrastructure end to end: context, a trivial kernel inside the validation scope,
//! buffer upload / read-back / grow, capacity errors, error scopes, timing.
//! Every trial shows as ignored without an adapter (tests/it/common/harness.rs).

use crate::common;

use common::harness::{gpu, skipped};
use libtest_mimic::Completion;
use wgslam::gpu::buffers::{GpuArray, ParamBuffer};
use wgslam::gpu::images::GpuImage;
use wgslam::gpu::pipeline_cache::CACHE_ENV;
use wgslam::gpu::shaders;
use wgslam::gpu::{GpuContext, Kernel, StageTimer};
use wgslam::Error;

/// `out[i] = 2 in[i] + offset` for `i < n`, using a helper from common.wgsl so the
/// concatenation is exercised too.
const AFFINE: &str = r#"
struct AffineParams { n: u32, offset: u32, _a: u32, _b: u32 }
@group(0) @binding(0) var<storage, read> params: AffineParams;
@group(0) @binding(1) var<storage, read> input: array<u32>;
@group(0) @binding(2) var<storage, read_write> output: array<u32>;

@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= params.n {
        return;
    }
    // is_valid comes from common.wgsl.
    let bonus = select(0u, 1000u, is_valid(vec4<f32>(0.0, 0.0, 0.0, f32(i % 2u))));
    output[i] = 2u * input[i] + params.offset + bonus;
}
"#;

#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct AffineParams {
    n: u32,
    offset: u32,
    _a: u32,
    _b: u32,
}

fn trivial_kernel_runs_in_validation_scope(ctx: GpuContext) {
    eprintln!(
        "adapter {:?}, reduction workgroups {}, max storage binding {} bytes, features {:?}",
        ctx.adapter_info().name,
        ctx.reduction_workgroups(),
        ctx.limits().max_storage_buffer_binding_size,
        ctx.features()
    );
    // 1000 is not a multiple of 64: the last workgroup is partial.
    let n = 1000usize;
    let input: Vec<u32> = (0..n as u32).map(|i| i * 7 % 97).collect();
    let got = ctx
        .scoped("affine smoke kernel", || {
            let kernel = Kernel::from_source(&ctx, "affine", &shaders::concat_with_common(AFFINE))?;
            assert_eq!(kernel.workgroup_size, 64);
            assert_eq!(kernel.workgroups_for(n), 16);
            let params = ParamBuffer::new(
                &ctx,
                "affine params",
                &AffineParams {
                    n: n as u32,
                    offset: 5,
                    _a: 0,
                    _b: 0,
                },
            );
            let inp = GpuArray::from_slice(&ctx, "input", &input)?;
            let mut out = GpuArray::<u32>::new(&ctx, "output", n)?;
            out.set_len(n);
            let bg = kernel.bind_group(
                &ctx,
                &[
                    ("params", params.binding()),
                    ("input", inp.binding()),
                    ("output", out.binding()),
                ],
            );
            let mut timer = StageTimer::new(&ctx, 4);
            let mut enc = ctx.encoder("affine");
            {
                let mut pass = timer.begin_pass(&mut enc, "affine");
                kernel.dispatch(&ctx, &mut pass, &bg, kernel.workgroups_for(n))?;
                // An empty dispatch is skipped, not an error.
                kernel.dispatch(&ctx, &mut pass, &bg, 0)?;
            }
            timer.resolve(&mut enc);
            ctx.submit(enc);
            let times = timer.read(&ctx)?;
            assert_eq!(times.len(), 1, "one timed stage: {times:?}");
            assert!(times[0].ms >= 0.0 && times[0].ms.is_finite());
            eprintln!("stage times: {times:?}");
            out.read_back(&ctx)
        })
        .expect("no GPU error");
    for (i, (&g, &x)) in got.iter().zip(&input).enumerate() {
        let want = 2 * x + 5 + if i % 2 == 1 { 1000 } else { 0 };
        assert_eq!(g, want, "element {i}: GPU {g}, expected {want}");
    }
    let stats = ctx.stats();
    assert!(stats.submissions >= 2, "{stats:?}");
    assert_eq!(stats.readback_bytes, (n * 4) as u64, "{stats:?}");
}

fn int64_atomic_max_packs_depth_and_index(ctx: GpuContext) -> Completion {
    // The adapter's own features, whatever WGSLAM_GPU_FEATURES / WGSLAM_GPU_LIMITS ask of
    // the other tests' devices: this checks what the 64-bit kernels rely on.
    drop(ctx);
    let ctx = GpuContext::with_options(wgslam::gpu::context::DeviceOptions::default())
        .expect("a device with the adapter's features");
    if !ctx.has_int64_atomics() {
        return skipped("adapter has no 64-bit atomics");
    }
    const SRC: &str = r#"
@group(0) @binding(0) var<storage, read> keys: array<u32>;
@group(0) @binding(1) var<storage, read_write> best: array<atomic<u64>>;
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x;
    if i >= arrayLength(&keys) { return; }
    atomicMax(&best[i % 4u], (u64(keys[i]) << 32u) | u64(i));
}
"#;
    let keys: Vec<u32> = (0..256u32)
        .map(|i| i.wrapping_mul(2654435761) >> 8)
        .collect();
    let got = ctx
        .scoped("u64 atomicMax", || {
            let k = Kernel::from_source(&ctx, "atomic64", &shaders::concat_with_common(SRC))?;
            let keys_buf = GpuArray::from_slice(&ctx, "keys", &keys)?;
            let mut best = GpuArray::<u64>::new(&ctx, "best", 4)?;
            best.set_len(4);
            let bg = k.bind_group(
                &ctx,
                &[("keys", keys_buf.binding()), ("best", best.binding())],
            );
            let mut enc = ctx.encoder("atomic64");
            best.clear(&mut enc);
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                k.dispatch(&ctx, &mut pass, &bg, k.workgroups_for(keys.len()))?;
            }
            ctx.submit(enc);
            best.read_back(&ctx)
        })
        .expect("no GPU error");
    for (slot, &g) in got.iter().enumerate() {
        let want = keys
            .iter()
            .enumerate()
            .filter(|(i, _)| i % 4 == slot)
            .map(|(i, &k)| (k as u64) << 32 | i as u64)
            .max()
            .unwrap();
        assert_eq!(g, want, "slot {slot}");
    }
    Completion::Completed
}

fn arrays_grow_keeping_contents_and_read_back_ranges(ctx: GpuContext) {
    let data: Vec<[f32; 4]> = (0..100).map(|i| [i as f32, 1.0, 2.0, 3.0]).collect();
    let mut a = GpuArray::from_slice(&ctx, "positions", &data).unwrap();
    let before = ctx.stats().allocated_bytes;
    a.grow(&ctx, 1000).unwrap();
    assert_eq!(a.capacity(), 1000);
    assert_eq!(a.len(), 100);
    assert_eq!(ctx.stats().allocated_bytes, before + 900 * 16);
    assert_eq!(a.read_back(&ctx).unwrap(), data);
    assert_eq!(
        a.read_back_range(&ctx, 10..13).unwrap(),
        data[10..13].to_vec()
    );
    // Elements past len are zero after growing.
    assert_eq!(a.read_back_range(&ctx, 500..501).unwrap(), vec![[0.0; 4]]);
    // u16 data (odd byte counts) round-trips through padding.
    let depth: Vec<u16> = vec![1, 2, 3];
    let d = GpuArray::from_slice(&ctx, "depth", &depth).unwrap();
    assert_eq!(d.read_back(&ctx).unwrap(), depth);
    assert_eq!(d.read_back_range(&ctx, 1..2).unwrap(), vec![2]);
    drop(a);
    assert_eq!(ctx.stats().allocated_bytes, before - 100 * 16 + 8);
}

fn capacity_past_the_binding_limit_is_an_error(ctx: GpuContext) {
    let too_many = (ctx.max_storage_bytes() / 16 + 1) as usize;
    match GpuArray::<[f32; 4]>::new(&ctx, "surfel positions", too_many) {
        Err(Error::Capacity(msg)) => {
            assert!(msg.contains("surfel positions") && msg.contains(&too_many.to_string()));
            eprintln!("{msg}");
        }
        other => panic!("expected Error::Capacity, got {other:?}"),
    }
}

fn validation_errors_become_gpu_errors(ctx: GpuContext) {
    // Copying past the end of a buffer is a validation error.
    let a = GpuArray::<u32>::new(&ctx, "small", 4).unwrap();
    let b = GpuArray::<u32>::new(&ctx, "smaller", 1).unwrap();
    let r = ctx.scoped("bad copy", || {
        let mut enc = ctx.encoder("bad copy");
        enc.copy_buffer_to_buffer(a.buffer(), 0, b.buffer(), 0, 16);
        ctx.submit(enc);
        Ok(())
    });
    match r {
        Err(Error::Gpu(msg)) => assert!(msg.starts_with("bad copy:"), "{msg}"),
        other => panic!("expected Error::Gpu, got {other:?}"),
    }
    // The context stays usable afterwards.
    ctx.scoped("good work", || Ok(())).unwrap();
}

/// Textures whose rows are not a multiple of the 256-byte copy pitch read back without
/// the padding; a prefix upload zero-fills the rest of its last row and leaves later rows.
fn images_round_trip_unaligned_rows_and_prefixes(ctx: GpuContext) {
    // 213 texels x 16 bytes = 3408 bytes per row: not a multiple of 256.
    let (w, h) = (213u32, 5u32);
    let image = GpuImage::new(
        &ctx,
        "test image",
        w,
        h,
        wgpu::TextureFormat::Rgba32Float,
        true,
    )
    .unwrap();
    let full: Vec<[f32; 4]> = (0..w * h).map(|i| [i as f32, 1.0, 2.0, 3.0]).collect();
    image.upload(&ctx, &full).unwrap();
    assert_eq!(image.read_back::<[f32; 4]>(&ctx).unwrap(), full);
    // Overwrite the first 300 texels (one row and 87 texels of the next) with -1.
    let prefix = vec![[-1.0f32; 4]; 300];
    image.upload_prefix(&ctx, &prefix).unwrap();
    let back: Vec<[f32; 4]> = image.read_back(&ctx).unwrap();
    assert_eq!(&back[..300], &prefix[..]);
    assert!(back[300..2 * w as usize].iter().all(|t| *t == [0.0; 4]));
    assert_eq!(&back[2 * w as usize..], &full[2 * w as usize..]);
    assert_eq!(
        image.read_back_prefix::<[f32; 4]>(&ctx, 250).unwrap(),
        back[..250]
    );
    // Wrong texel size and oversized uploads are errors, not panics.
    assert!(matches!(
        image.read_back::<u32>(&ctx),
        Err(Error::Argument(_))
    ));
    assert!(matches!(
        image.upload_prefix(&ctx, &vec![[0.0f32; 4]; (w * h + 1) as usize]),
        Err(Error::Argument(_))
    ));
}

/// A bind group is made by binding name: a resource under a wrong name, a missing one and
/// a buffer for a texture binding each stop it with the kernel's and the binding's name.
fn bind_groups_fail_by_kernel_and_binding_name(ctx: GpuContext) {
    let kernel = Kernel::from_source(&ctx, "affine", &shaders::concat_with_common(AFFINE))
        .expect("affine kernel");
    let params = GpuArray::<u32>::from_slice(&ctx, "params", &[0; 4]).expect("buffer");
    let input = GpuArray::<u32>::from_slice(&ctx, "input", &[0; 4]).expect("buffer");
    let panic_message = |resources: &[(&str, wgpu::BindingResource)]| {
        let err = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            kernel.bind_group(&ctx, resources);
        }))
        .expect_err("a wrong bind group must not be made");
        err.downcast_ref::<String>().cloned().unwrap_or_default()
    };
    // `outptu` for `output`: an unknown name, and binding 2 left without a resource.
    let msg = panic_message(&[
        ("params", params.binding()),
        ("input", input.binding()),
        ("outptu", input.binding()),
    ]);
    assert!(msg.contains("kernel `affine`"), "{msg}");
    assert!(msg.contains("`outptu` is not one of its bindings"), "{msg}");
    assert!(
        msg.contains("binding 2 (`output`) has no resource"),
        "{msg}"
    );
    // The same name twice.
    let msg = panic_message(&[
        ("params", params.binding()),
        ("input", input.binding()),
        ("input", input.binding()),
        ("output", input.binding()),
    ]);
    assert!(
        msg.contains("binding 1 (`input`) is given 2 resources"),
        "{msg}"
    );
    // A texture where the kernel declares a buffer.
    let image =
        GpuImage::new(&ctx, "image", 2, 2, wgpu::TextureFormat::Rgba32Float, true).expect("image");
    let msg = panic_message(&[
        ("params", params.binding()),
        ("input", image.binding()),
        ("output", input.binding()),
    ]);
    assert!(msg.contains("binding 1 (`input`)"), "{msg}");
    assert!(msg.contains("given a texture"), "{msg}");
}

/// A headless run's first lines are wgslam's own (issue 32, item 7): without a valid
/// `XDG_RUNTIME_DIR`, Mesa's device-selection layer used to make libwayland print "error:
/// XDG_RUNTIME_DIR is invalid or not set in the environment." twice before them.
fn headless_run_prints_no_window_system_error(_ctx: GpuContext) {
    let dir = common::temp_dir("gpu-smoke-headless");
    let out = dir.join("out");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_wgslam"))
        .args([
            "run",
            "--backend",
            "gpu",
            "--frames",
            "1..2",
            "--downsample",
            "4",
            "--out",
        ])
        .arg(&out)
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("NODEVICE_SELECT")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("run wgslam");
    let text = common::cli::text(&o);
    assert!(o.status.success(), "{text}");
    assert!(
        !text.contains("XDG_RUNTIME_DIR"),
        "a window-system message reached a headless run's output:\n{text}"
    );
}

/// Two one-frame GPU runs sharing a pipeline cache folder of this test's own: the first
/// writes the cache file (on adapters wgpu keeps one for: Vulkan), garbage in its place is
/// a note on the second run, which still succeeds and writes a good file back.
fn a_corrupt_pipeline_cache_is_a_note_and_is_replaced(_ctx: GpuContext) {
    let dir = common::temp_dir("gpu-smoke-pipeline-cache");
    let cache = dir.join("cache");
    let run = |out: &str| {
        let out = dir.join(out).display().to_string();
        let args = [
            "run",
            "--backend",
            "gpu",
            "--frames",
            "1..1",
            "--downsample",
            "4",
        ];
        let env = [(CACHE_ENV, cache.to_str().unwrap())];
        let o = common::cli::wgslam_env(&[&args[..], &["--out", &out]].concat(), &env);
        let text = common::cli::text(&o);
        assert!(o.status.success(), "{text}");
        text
    };
    run("o1");
    let files: Vec<_> =
        std::fs::read_dir(&cache).map_or(Vec::new(), |d| d.map(|e| e.unwrap().path()).collect());
    let Some(file) = files.first() else {
        return; // not a Vulkan adapter: wgpu keeps no cache file
    };
    assert_eq!(files.len(), 1, "one file, no temporary left: {files:?}");
    std::fs::write(file, b"not a pipeline cache").unwrap();
    let text = run("o2");
    assert!(
        text.contains("note: the pipeline cache") && text.contains("starting an empty one"),
        "{text}"
    );
    assert_ne!(std::fs::read(file).unwrap(), b"not a pipeline cache");
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        gpu(
            "headless_run_prints_no_window_system_error",
            headless_run_prints_no_window_system_error,
        ),
        gpu(
            "a_corrupt_pipeline_cache_is_a_note_and_is_replaced",
            a_corrupt_pipeline_cache_is_a_note_and_is_replaced,
        ),
        gpu(
            "trivial_kernel_runs_in_validation_scope",
            trivial_kernel_runs_in_validation_scope,
        ),
        gpu(
            "bind_groups_fail_by_kernel_and_binding_name",
            bind_groups_fail_by_kernel_and_binding_name,
        ),
        gpu(
            "int64_atomic_max_packs_depth_and_index",
            int64_atomic_max_packs_depth_and_index,
        ),
        gpu(
            "arrays_grow_keeping_contents_and_read_back_ranges",
            arrays_grow_keeping_contents_and_read_back_ranges,
        ),
        gpu(
            "capacity_past_the_binding_limit_is_an_error",
            capacity_past_the_binding_limit_is_an_error,
        ),
        gpu(
            "validation_errors_become_gpu_errors",
            validation_errors_become_gpu_errors,
        ),
        gpu(
            "images_round_trip_unaligned_rows_and_prefixes",
            images_round_trip_unaligned_rows_and_prefixes,
        ),
    ]
}
