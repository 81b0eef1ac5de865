//! Storage-buffer loads vs texture loads on the current adapter: the measurement behind
//! keeping per-pixel maps and the surfel map in textures (`crates/gpu/src/images.rs`).
//!
//! Three access patterns, each written once reading a `array<vec4<f32>>` storage buffer
//! and once reading a `texture_2d<f32>` (rgba32float) with `textureLoad`, writing the same
//! storage buffer: a 5-point stencil over 640x480 (like `vertex_to_normal`), a sequential
//! pass over 1.3M entries (like `project_model`), and a gather of 307k entries at scattered
//! indices from 1.3M (like `predict_model`). Prints the fastest of several dispatches.
//!
//! `cargo run --release --example lavapipe_loads`

use std::time::Instant;

use wgpu::util::DeviceExt;
use wgslam::gpu::images::GpuImage;
use wgslam::gpu::GpuContext;

const W: u32 = 640;
const H: u32 = 480;
/// Rows of the 1.3M-entry table when it is a texture 4096 texels wide.
const TABLE_ROWS: u32 = 320;
const REPETITIONS: usize = 10;

/// Common WGSL: the frame size, the table width, and the output and index bindings.
const HEADER: &str = "const W: u32 = 640u; const H: u32 = 480u; const TW: u32 = 4096u;
@group(0) @binding(1) var<storage, read_write> dst: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> idx: array<u32>;
";
/// The source binding of the storage-buffer variants.
const SRC_BUFFER: &str = "@group(0) @binding(0) var<storage, read> src: array<vec4<f32>>;\n";
/// The source binding of the texture variants.
const SRC_TEXTURE: &str = "@group(0) @binding(0) var src: texture_2d<f32>;\n";

const STENCIL_BUFFER: &str = "
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x; let u = i % W; let v = i / W;
    if u == 0u || v == 0u || u + 1u >= W || v + 1u >= H || idx[0] == 1u { return; }
    dst[i] = src[i] + src[i - 1u] + src[i + 1u] + src[i - W] + src[i + W];
}";
const STENCIL_TEXTURE: &str = "
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let i = gid.x; let u = i % W; let v = i / W;
    if u == 0u || v == 0u || u + 1u >= W || v + 1u >= H || idx[0] == 1u { return; }
    dst[i] = textureLoad(src, vec2(u, v), 0) + textureLoad(src, vec2(u - 1u, v), 0)
        + textureLoad(src, vec2(u + 1u, v), 0) + textureLoad(src, vec2(u, v - 1u), 0)
        + textureLoad(src, vec2(u, v + 1u), 0);
}";
const SEQUENTIAL_BUFFER: &str = "
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = src[gid.x];
    if p.x + p.y + p.z < -1.0 || idx[0] == 1u { dst[0] = p; }
}";
const SEQUENTIAL_TEXTURE: &str = "
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let p = textureLoad(src, vec2(gid.x % TW, gid.x / TW), 0);
    if p.x + p.y + p.z < -1.0 || idx[0] == 1u { dst[0] = p; }
}";
const GATHER_BUFFER: &str = "
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    dst[gid.x] = src[idx[gid.x]];
}";
const GATHER_TEXTURE: &str = "
@compute @workgroup_size(64)
fn main(@builtin(global_invocation_id) gid: vec3<u32>) {
    let k = idx[gid.x];
    dst[gid.x] = textureLoad(src, vec2(k % TW, k / TW), 0);
}";

fn main() -> wgslam::Result<()> {
    let ctx = GpuContext::new()?;
    let d = &ctx.device;
    let pixels = W * H;
    let table = 4096 * TABLE_ROWS;
    let data: Vec<[f32; 4]> = (0..table).map(|i| [i as f32, 1.0, 2.0, 1.0]).collect();
    let buffer = |contents: &[u8]| {
        d.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: None,
            contents,
            usage: wgpu::BufferUsages::STORAGE,
        })
    };
    let texture = |width: u32, height: u32| -> wgslam::Result<GpuImage> {
        let image = GpuImage::new(
            &ctx,
            "source",
            width,
            height,
            wgpu::TextureFormat::Rgba32Float,
            false,
        )?;
        image.upload(&ctx, &data[..(width * height) as usize])?;
        Ok(image)
    };
    let src_buffer = buffer(bytemuck::cast_slice(&data));
    let frame_texture = texture(W, H)?;
    let table_texture = texture(4096, TABLE_ROWS)?;
    let dst = buffer(&vec![0u8; pixels as usize * 16]);
    // Scattered indices (a multiplicative hash), the same for both variants.
    let scattered: Vec<u32> = (0..pixels)
        .map(|i| i.wrapping_mul(2_654_435_761) % table)
        .collect();
    let idx = buffer(bytemuck::cast_slice(&scattered));

    let time = |src_decl: &str, code: &str, src: wgpu::BindingResource, threads: u32| -> f64 {
        let module = d.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: None,
            source: wgpu::ShaderSource::Wgsl(format!("{HEADER}{src_decl}{code}").into()),
        });
        let pipeline = d.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: None,
            layout: None,
            module: &module,
            entry_point: Some("main"),
            compilation_options: Default::default(),
            cache: None,
        });
        let bind_group = d.create_bind_group(&wgpu::BindGroupDescriptor {
            label: None,
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: src,
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: dst.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: idx.as_entire_binding(),
                },
            ],
        });
        let mut best = f64::MAX;
        // The first dispatch compiles the shader: not timed.
        for rep in 0..=REPETITIONS {
            let mut enc = d.create_command_encoder(&Default::default());
            {
                let mut pass = enc.begin_compute_pass(&Default::default());
                pass.set_pipeline(&pipeline);
                pass.set_bind_group(0, &bind_group, &[]);
                pass.dispatch_workgroups(threads / 64, 1, 1);
            }
            let t = Instant::now();
            ctx.queue.submit(Some(enc.finish()));
            if let Err(e) = d.poll(wgpu::PollType::wait_indefinitely()) {
                eprintln!("poll failed: {e}");
                return f64::NAN;
            }
            if rep > 0 {
                best = best.min(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        best
    };
    let rows = [
        (
            "5-point stencil, 640x480",
            time(
                SRC_BUFFER,
                STENCIL_BUFFER,
                src_buffer.as_entire_binding(),
                pixels,
            ),
            time(
                SRC_TEXTURE,
                STENCIL_TEXTURE,
                frame_texture.binding(),
                pixels,
            ),
        ),
        (
            "sequential, 1.3M entries",
            time(
                SRC_BUFFER,
                SEQUENTIAL_BUFFER,
                src_buffer.as_entire_binding(),
                table,
            ),
            time(
                SRC_TEXTURE,
                SEQUENTIAL_TEXTURE,
                table_texture.binding(),
                table,
            ),
        ),
        (
            "gather 307k of 1.3M",
            time(
                SRC_BUFFER,
                GATHER_BUFFER,
                src_buffer.as_entire_binding(),
                pixels,
            ),
            time(SRC_TEXTURE, GATHER_TEXTURE, table_texture.binding(), pixels),
        ),
    ];
    println!("fastest of {REPETITIONS} dispatches, milliseconds");
    for (name, buffer_ms, texture_ms) in rows {
        println!(
            "{name:<26} storage buffer {buffer_ms:7.2}  texture {texture_ms:7.2}  texture {:.1}x faster",
            buffer_ms / texture_ms
        );
    }
    Ok(())
}
