//! `wgslam render`: arguments and the run function (dispatched from `cli/mod.rs`).
//!
//! Reads a PLY point cloud or surfel map, renders it from a default viewpoint framing the
//! whole cloud (or from `--pose`), writes one PNG. Argument checking and printing only; the
//! drawing is `crate::render`.

use std::path::{Path, PathBuf};

use glam::DVec3;

use crate::geometry::camera::Intrinsics;
use crate::gpu::GpuContext;
use crate::io::ply::{read_ply, PlyCloud};
use crate::io::trajectory::{parse_tum, read_tum};
use crate::render::gpu::GpuRenderer;
use crate::render::outputs::map_view_hint;
use crate::render::{
    default_camera, parse_size, write_png, Cloud, RenderBackend, RenderCamera, RenderSettings, View,
};
use crate::slam::any_backend::BackendChoice;
use crate::{Error, Result};

/// `wgslam render MAP.ply [--pose ...] [--view ...] [--size WxH] -o OUT.png`
#[derive(Debug, Clone, clap::Args)]
pub struct RenderArgs {
    /// PLY file to draw (a wgslam map.ply, or any PLY with vertex x y z; normals, colours and
    /// weights are used when present).
    pub map: PathBuf,
    /// Camera pose (camera-to-world): one TUM line `stamp tx ty tz qx qy qz qw`, or a TUM
    /// trajectory file (its last pose is used). Default: a viewpoint framing the whole map.
    #[arg(long)]
    pub pose: Option<String>,
    /// What to show: color, normals (world-frame normal as RGB), weight, or depth.
    #[arg(long, default_value = "color")]
    pub view: String,
    /// Image size, WIDTHxHEIGHT pixels (at most 16384 per side).
    #[arg(long, default_value = "960x720")]
    pub size: String,
    /// Camera model of the data: icl (negative fy), fr1, fr2, fr3. Gives the intrinsics of
    /// --pose (scaled to --size) and the handedness of the default view.
    #[arg(long, default_value = "icl")]
    pub camera: String,
    /// World up axis for the default view: x, y, z, -x, -y or -z (ICL-NUIM: y).
    #[arg(long, default_value = "y", allow_hyphen_values = true)]
    pub up: String,
    /// World radius of one splat, metres.
    #[arg(long, default_value_t = 0.01)]
    pub splat_radius: f32,
    /// Fill empty pixels between drawn ones at most this many pixels apart (above and
    /// below, or left and right) at the same depth: the gaps between rows of surfels seen
    /// at a grazing angle; 0 draws the splats only.
    #[arg(long, default_value_t = crate::render::DEFAULT_FILL_GAP_PX)]
    pub fill_gaps: u32,
    /// Draw surfels that face away from the camera too (by default they are hidden, so a
    /// viewpoint outside a room sees in through its walls).
    #[arg(long)]
    pub no_cull: bool,
    /// Which implementation draws: auto (the GPU when a Vulkan, Metal or DX12 adapter
    /// exists, otherwise the CPU, saying so), cpu or gpu.
    #[arg(long, value_enum, default_value_t = BackendChoice::Auto)]
    pub backend: BackendChoice,
    /// Output PNG (written completely or not at all).
    #[arg(short = 'o', long = "out")]
    pub out: PathBuf,
}

/// What `run_render` did, for the caller to print.
#[derive(Debug, Clone)]
pub struct RenderReport {
    pub points: usize,
    /// The view drawn (a depth view when the requested attribute is missing).
    pub view: View,
    pub size: (u32, u32),
    /// `cpu` or `gpu`: what drew it.
    pub backend: &'static str,
    /// One sentence per problem met that did not stop the render (missing attributes).
    pub warnings: Vec<String>,
}

/// Parses an up axis name.
pub fn parse_axis(s: &str) -> Result<DVec3> {
    match s.trim().to_ascii_lowercase().as_str() {
        "x" | "+x" => Ok(DVec3::X),
        "y" | "+y" => Ok(DVec3::Y),
        "z" | "+z" => Ok(DVec3::Z),
        "-x" => Ok(DVec3::NEG_X),
        "-y" => Ok(DVec3::NEG_Y),
        "-z" => Ok(DVec3::NEG_Z),
        _ => Err(Error::Argument(format!(
            "unknown axis `{s}` (expected x, y, z, -x, -y or -z)"
        ))),
    }
}

/// The camera-to-world pose of `--pose`: an existing file is read as a TUM trajectory (last
/// pose), anything else is parsed as one TUM line.
pub fn parse_pose(arg: &str) -> Result<glam::DMat4> {
    let path = Path::new(arg);
    let poses = if path.is_file() {
        read_tum(path)?
    } else {
        parse_tum(Path::new("--pose"), arg)?
    };
    poses.last().map(|p| p.1).ok_or_else(|| {
        Error::Argument(format!(
            "--pose `{arg}` holds no pose (expected `stamp tx ty tz qx qy qz qw` or a TUM file)"
        ))
    })
}

/// `k` rescaled to a `width` x `height` image (each axis by its own factor).
pub fn scale_intrinsics(k: &Intrinsics, width: u32, height: u32) -> Intrinsics {
    let sx = width as f32 / k.width as f32;
    let sy = height as f32 / k.height as f32;
    Intrinsics {
        width,
        height,
        fx: k.fx * sx,
        fy: k.fy * sy,
        cx: (k.cx + 0.5) * sx - 0.5,
        cy: (k.cy + 0.5) * sy - 0.5,
    }
}

/// The cloud's arrays in the renderer's layout (`vec4` positions/normals, float colours).
struct Arrays {
    positions: Vec<[f32; 4]>,
    normals: Option<Vec<[f32; 4]>>,
    colors: Option<Vec<[f32; 4]>>,
    weights: Option<Vec<f32>>,
}

impl Arrays {
    fn from_ply(ply: PlyCloud) -> Arrays {
        let v4 = |v: &[f32; 3], w: f32| [v[0], v[1], v[2], w];
        Arrays {
            positions: ply.positions.iter().map(|p| v4(p, 1.0)).collect(),
            normals: ply.normals.map(|n| n.iter().map(|v| v4(v, 0.0)).collect()),
            colors: ply.colors.map(|c| {
                c.iter()
                    .map(|c| [c[0] as f32, c[1] as f32, c[2] as f32, 255.0])
                    .collect()
            }),
            weights: ply.weights,
        }
    }

    fn cloud(&self) -> Cloud<'_> {
        Cloud {
            positions: &self.positions,
            normals: self.normals.as_deref(),
            colors: self.colors.as_deref(),
            weights: self.weights.as_deref(),
        }
    }
}

/// Runs `wgslam render`: reads, renders, writes `args.out`.
pub fn run_render(args: &RenderArgs) -> Result<RenderReport> {
    // Check every argument before the (possibly large) file is read.
    let view = View::parse(&args.view)?;
    let (width, height) = parse_size(&args.size)?;
    let k = Intrinsics::preset(&args.camera).ok_or_else(|| {
        Error::Argument(format!(
            "unknown camera `{}` (expected icl, fr1, fr2 or fr3)",
            args.camera
        ))
    })?;
    let up = parse_axis(&args.up)?;
    let pose = args.pose.as_deref().map(parse_pose).transpose()?;
    if !(args.splat_radius > 0.0 && args.splat_radius.is_finite()) {
        return Err(Error::Argument(format!(
            "--splat-radius {} must be a positive number of metres",
            args.splat_radius
        )));
    }

    let arrays = Arrays::from_ply(read_ply(&args.map)?);
    if arrays.positions.is_empty() {
        return Err(Error::format(
            &args.map,
            "the PLY file has no vertex to draw",
        ));
    }
    let cloud = arrays.cloud();
    let mut warnings = Vec::new();
    let missing: Vec<&str> = [
        ("normals", cloud.normals.is_none()),
        ("colours", cloud.colors.is_none()),
        ("weights", cloud.weights.is_none()),
    ]
    .iter()
    .filter(|(_, m)| *m)
    .map(|(n, _)| *n)
    .collect();
    if !missing.is_empty() {
        warnings.push(format!(
            "{} has no {}",
            args.map.display(),
            missing.join(", ")
        ));
    }
    let (used, why) = cloud.usable_view(view);
    warnings.extend(why);

    let camera = match pose {
        Some(t) => RenderCamera {
            t_cam_to_world: t,
            intrinsics: scale_intrinsics(&k, width, height),
        },
        None => {
            let (up, heading) = map_view_hint(cloud.normals, up);
            default_camera(&arrays.positions, width, height, up, heading, k.fy < 0.0)?
        }
    };
    let settings = RenderSettings {
        splat_radius_m: args.splat_radius,
        cull_backfaces: !args.no_cull,
        fill_gap_px: args.fill_gaps,
        ..RenderSettings::default()
    };
    let gpu = open_gpu(args.backend, &mut warnings)?;
    let backend = match &gpu {
        Some((ctx, kernels)) => RenderBackend::Gpu { ctx, kernels },
        None => RenderBackend::Cpu,
    };
    let img = backend.render(&cloud, &camera, used, &settings)?;
    write_png(&args.out, &img)?;
    Ok(RenderReport {
        points: arrays.positions.len(),
        view: used,
        size: (width, height),
        backend: backend.name(),
        warnings,
    })
}

/// The GPU context and render kernels for `choice`: `None` for the CPU. `Auto` falls back to
/// the CPU with a warning when no suitable adapter exists; `Gpu` fails instead.
pub fn open_gpu(
    choice: BackendChoice,
    warnings: &mut Vec<String>,
) -> Result<Option<(GpuContext, GpuRenderer)>> {
    if choice == BackendChoice::Cpu {
        return Ok(None);
    }
    let opened = GpuContext::new().and_then(|ctx| {
        let kernels = GpuRenderer::new(&ctx)?;
        Ok((ctx, kernels))
    });
    match (opened, choice) {
        (Ok(pair), _) => Ok(Some(pair)),
        (Err(e), BackendChoice::Auto) => {
            warnings.push(format!("no usable GPU ({e}); drawing on the CPU"));
            Ok(None)
        }
        (Err(e), _) => Err(e),
    }
}

/// Runs `wgslam render`, printing the warnings and what was drawn.
pub fn execute(a: RenderArgs) -> Result<()> {
    let r = run_render(&a)?;
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
    println!(
        "rendered {} points ({:?} view, {}x{}, {})",
        r.points, r.view, r.size.0, r.size.1, r.backend
    );
    Ok(())
}
