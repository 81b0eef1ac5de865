//! The kernel registry: one row per kernel, pairing its shader `shaders/<name>.wgsl` with
//! its CPU twin `crate::cpu::<name>::<name>` (the model is vello's
//! `add_shader!(name, ..., CpuShaderType::Present(cpu::name))`). Every fact about a kernel
//! that either backend needs is in its row, and every list of kernels is made from the
//! rows by the `registry_data!` macro below:
//!
//! - [`KernelId`], one variant per kernel, named after it: what a plan call
//!   (`crate::plan`) names, so a backend finds a kernel by a typed id that cannot be
//!   misspelt, never by its name; with each kernel's [`KernelId::name`];
//! - [`KERNELS`], every kernel's `(name, text of its file)` for the GPU engine and the naga
//!   tests, with a second entry over the same text for each key kernel's portable variant;
//! - [`PORTABLE_KERNELS`], the key kernels (rows marked `key`) with their portable
//!   variants' names, and [`SCAN_KERNELS`], the kernels prefixed with `scan_common.wgsl`
//!   (the `scan` group);
//! - [`GENERIC_KERNELS`], the kernels bound and dispatched by their rows alone;
//! - in the GPU engine (`wgslam_gpu::pipelines`, from the same rows, through the
//!   [`pipeline_rows!`](crate::pipeline_rows) macro the rows define), the dense pipeline's
//!   pipelines, one field per kernel named after it, and for the `generic` rows their
//!   [`Shape`] and the uniform bound as the kernel's `params`: its bind groups and passes
//!   then need nothing of their own for it;
//! - for the rows their callers bind (the renderer's, scan registration's:
//!   [`Shape::bound_by_caller`]), their [`Shape`] and uniform likewise, by which
//!   `wgslam_gpu::row_kernels` and [`run_call`](crate::cpu_backend::run_call) bind and
//!   dispatch a plan call over the caller's pool;
//! - a compile-time check that each row's twin exists (an underscore import of
//!   `crate::cpu::<name>::<name>`): a row without a twin does not build.
//!
//! The registry is on the bottom floor with the shaders' texts and the twins, so the plans
//! (`crate::plan`) name its ids and the GPU engine above builds from its rows. What it does
//! not hold: a kernel's bindings (reflected from the WGSL by the GPU engine, and bound by
//! the WGSL variables' names), the bind groups and passes of the kernels that fit no
//! [`Shape`] (`wgslam_gpu`'s `bind_groups.rs` and `steps.rs`), and the order kernels run in
//! (`crate::plan`).

use crate::cpu::binding::Twin;

/// The text of `shaders/<name>.wgsl`.
macro_rules! shader_text {
    ($name:ident) => {
        include_str!(concat!("../../../shaders/", stringify!($name), ".wgsl"))
    };
}

/// How a `generic` row's kernel is bound and dispatched on the GPU: its bind groups take
/// what the kernel's WGSL declares from the frame's pool of named resources (and each map
/// chunk's), with the row's uniform as `params`; its passes follow the plan. A key
/// kernel's passes run in turn, each over every bind group before the next (the portable
/// kernel's second pass reads the first's result over the whole map).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Shape {
    /// One bind group over the frame's pool (and the buffers of the steps that make their
    /// own, once made: a row that binds one has no bind group before); one pass over the
    /// frame's pixels.
    OverFrame,
    /// One bind group per map chunk; per chunk a pass over the frame's pixels.
    PerChunk,
    /// One bind group per map chunk; per chunk a pass of one workgroup per culling block
    /// holding live surfels.
    PerBlock,
    /// One bind group per map chunk; per chunk holding culling blocks whose boxes are
    /// stale (fusion appended to them, or the map was compacted or uploaded) a pass of one
    /// workgroup per stale block, none where no box is stale.
    PerStaleBlock,
    /// One bind group per map chunk over the chunk's pool and the map-wide arrays alone
    /// (no frame's maps: such a kernel also runs before the first frame, on an uploaded
    /// map); per chunk a pass of the kernel's grid-stride workgroups over its live surfels
    /// (one thread per surfel, at most the adapter's grid cap; an empty pass for a chunk
    /// without).
    PerSurfel,
    /// One bind group per pair of a map chunk `s` and a chunk `d <= s` of the spare map
    /// (compaction's second map, of the same chunks; made on demand: before it a row of
    /// this shape has no bind group), and per surfel array (`position_weight`,
    /// `normal_frame`, `color`), over the map alone as `PerSurfel`'s: chunk `s` as
    /// `chunk`, its array as `surfel_array`, chunk `d` and its array as `out_chunk` and
    /// `out_surfel_array`; per pair and array, in that order (`s`, then `d`, then the
    /// array), a pass of the kernel's grid-stride workgroups over chunk `s`'s live surfels
    /// (as `PerSurfel`'s).
    PerChunkPair,
    /// One bind group per set of flags a plan scans ([`Scanned`]: fusion's new-surfel
    /// flags, the frame's `flags`, `offsets` and `block_sums`, from the first frame on;
    /// compaction's keep flags and theirs, made on demand), each with the surfel
    /// `counter`; a pass of one workgroup per block of `layout::SCAN_BLOCK` flags, at the
    /// plan call's [`At::scanned`].
    PerScanBlock,
    /// Bound as [`Shape::PerScanBlock`]; a pass of one workgroup (over the blocks' sums).
    OneWorkgroup,
    /// One bind group over the frame's pool (as `PerItem`'s, with the buffers of the steps
    /// that make their own: the candidates' `counts`); a pass of one workgroup per count
    /// the step reads back (its threads walk the frame's pixels in a grid-stride loop).
    PerCount,
    /// One bind group over the frame's pool (as `OverFrame`'s, with the buffers of the
    /// steps that make their own: the ferns', the keypoints'); a pass of one thread per item
    /// the step counts (ferns, keypoints), at most the adapter's reduction workgroups (a
    /// grid-stride loop covers the rest).
    PerItem,
    /// One bind group per pyramid level (and, for the levels that read level 0's vertex
    /// maps, per choice of them: see [`At`]) over that level's maps, named as at level 0
    /// (`vertex_map`, `normal_depth`, `pred_vertex`, `intensity_patch`, ...; the finer
    /// level's as `fine_vertex`, `fine_pred_vertex`, `fine_pred_normal`, and its intensity
    /// patches, at level 0 the colour map, as `fine_map`); a pass over the level's
    /// pixels, at the [`At`] the plan call gives. The row's uniform is the level's own
    /// (a `generic_levels` row): a level without it has no bind group.
    PerLevel,
    /// One bind group per pyramid level and [`System`] over the level's maps (as
    /// `PerLevel`'s at [`At::of_level`], with level 0's prediction as `level0_pred_vertex`
    /// and `pred_intensity`) and the system's partial systems (`partials`); a pass of the
    /// adapter's reduction workgroups (each writes one partial system, its threads walking
    /// the level's pixels in a grid-stride loop: `system_grid.wgsl`), at the plan call's
    /// [`At`]. The row's uniform is the frame's (the same at every level).
    Reduce,
    /// One bind group per [`System`] over its partial systems (`partials`) and their sum
    /// (`system`); a pass of one workgroup per entry of the system (`ICP_SYSTEM_LEN`), at
    /// the plan call's [`At::system`].
    PerSystem,
    /// A row its caller binds (the renderer's, scan registration's: outside the dense
    /// pipeline, over buffers of their own): per plan call one bind group over the caller's
    /// pool of named resources, the row's uniform the pool's resource of its name; a pass
    /// of one thread per point the caller counts (a scan's query, a surfel, a pixel), at
    /// least one workgroup and at most the device's per-dimension limit (the kernel's
    /// grid-stride loop covers the rest).
    PerPoint,
    /// Bound as [`Shape::PerPoint`]; a pass of the adapter's reduction workgroups, each
    /// writing one partial sum (its threads walk the points in a grid-stride loop).
    PerPartial,
}

impl Shape {
    /// Whether a row of this shape is bound over its caller's pool alone
    /// ([`Shape::PerPoint`], [`Shape::PerPartial`]), not over the dense pipeline's buffers.
    pub const fn bound_by_caller(self) -> bool {
        matches!(self, Shape::PerPoint | Shape::PerPartial)
    }

    /// Where a row of this shape has the bind groups a plan call at `at` runs over: a
    /// `PerLevel` row's at the call's choice of level and vertex maps ([`At::choice`]), a
    /// reduction's, a system's sum's and a scan's at the call's [`At`]; every other row's at
    /// [`At::FRAME`].
    pub fn bound_at(self, at: At) -> At {
        match self {
            Shape::PerLevel => at.choice(),
            Shape::Reduce | Shape::PerSystem | Shape::PerScanBlock | Shape::OneWorkgroup => at,
            _ => At::FRAME,
        }
    }
}

/// The normal-equation systems an ICP iteration reduces, each into partial systems of
/// its own and their sum: [`Shape::Reduce`] and [`Shape::PerSystem`] rows are bound per
/// system, and a plan call's [`At::system`] says which it writes or sums.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub enum System {
    /// The geometric (point-to-plane) term's.
    #[default]
    Geometric,
    /// RGB-D tracking's photometric term's.
    Photometric,
}

impl System {
    /// Every system, in the order of the pair `rgbd_system` returns (geometric first).
    pub const ALL: [System; 2] = [System::Geometric, System::Photometric];
}

/// The flags a scan covers: [`Shape::PerScanBlock`] and [`Shape::OneWorkgroup`] rows are
/// bound per set, and a plan call's [`At::scanned`] says which it scans.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub enum Scanned {
    /// Fusion's new-surfel flags, one per entry of append order.
    #[default]
    NewSurfels,
    /// Compaction's keep flags, one per surfel.
    KeepFlags,
}

/// Where a plan call's kernel runs, for a [`Shape::PerLevel`] row: pyramid level `level`
/// (0: the frame's own maps), and which of level 0's vertex maps it reads where it reads
/// one: its `vertex_map` (and level 1's `fine_vertex`) the filtered one when `filtered`,
/// its `point_map` the filtered one when `filtered_points`; for a [`Shape::Reduce`] or
/// [`Shape::PerSystem`] row, which [`System`] it writes or sums; for a scan's row, which
/// flags it scans ([`Scanned`]). Every other call is at [`At::FRAME`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash, Default)]
pub struct At {
    /// The pyramid level, 0 the finest.
    pub level: usize,
    /// Level 0's `vertex_map` (and level 1's `fine_vertex`) is the filtered vertex map.
    pub filtered: bool,
    /// Level 0's `point_map` is the filtered vertex map.
    pub filtered_points: bool,
    /// The system a reduction writes the partials of, or whose partials it sums.
    pub system: System,
    /// The flags a scan's kernel scans.
    pub scanned: Scanned,
}

impl At {
    /// Level 0, the unfiltered vertex maps: where every call of another [`Shape`] runs.
    pub const FRAME: At = At {
        level: 0,
        filtered: false,
        filtered_points: false,
        system: System::Geometric,
        scanned: Scanned::NewSurfels,
    };

    /// Pyramid level `level` for a kernel that reads none of level 0's vertex maps.
    pub const fn of_level(level: usize) -> At {
        At { level, ..At::FRAME }
    }

    /// A reduction's place: pyramid level `level` (the frame's at 0) and the [`System`] it
    /// writes or sums.
    pub const fn of_system(level: usize, system: System) -> At {
        At {
            level,
            system,
            ..At::FRAME
        }
    }

    /// A scan's place: the flags it scans.
    pub const fn of_scan(scanned: Scanned) -> At {
        At {
            scanned,
            ..At::FRAME
        }
    }

    /// Every [`At`] a plan may give at `level`: at levels 0 and 1 each choice of level 0's
    /// vertex maps the plans make (the filtered points only with the filtered normals);
    /// above them one (the choice reads nothing there).
    pub fn choices(level: usize) -> Vec<At> {
        let at = |filtered, filtered_points| At {
            level,
            filtered,
            filtered_points,
            ..At::FRAME
        };
        match level {
            0 => vec![at(false, false), at(true, true), at(true, false)],
            1 => vec![at(false, false), at(true, false)],
            _ => vec![at(false, false)],
        }
    }

    /// This call's [`At`] as [`At::choices`] lists it: what it does not read dropped.
    pub fn choice(self) -> At {
        At {
            level: self.level,
            filtered: self.level <= 1 && self.filtered,
            filtered_points: self.level == 0 && self.filtered_points,
            ..At::FRAME
        }
    }
}

/// The [`Twin`] of a row: `None`, or for a `bound` row its twin in the one call shape.
macro_rules! twin_of {
    ($name:ident) => {
        None
    };
    ($name:ident bound) => {
        Some(Twin {
            run: crate::cpu::$name::$name,
            bindings: crate::cpu::$name::BINDINGS,
        })
    };
}

/// One row per kernel, in groups by how the kernel is built and run. The `key` groups hold
/// the key kernels, which keep the nearest surfel per pixel in a map of 64-bit keys (on the
/// GPU a `KeyKernel`: the 64-bit kernel, or on a device without 64-bit atomics its portable
/// variant `<name>_portable`, the same file built without `KEY_64`; both are in
/// [`KERNELS`] and [`PORTABLE_KERNELS`]).
///
/// - `generic`, `generic_keys`: `name: Shape(uniform)`, a kernel whose bind groups and
///   passes the row decides ([`Shape`]; `uniform` is the GPU engine's `Uniforms` field bound
///   as its `params`): nothing else in `crates/gpu/src/` names it; a row ending in `bound`
///   has a twin in the one call shape (`crate::cpu::binding`), which the CPU backend runs
///   through the row ([`KernelId::twin`]) as the GPU engine does;
/// - `generic_levels`: the same for a kernel over one pyramid level's maps
///   ([`Shape::PerLevel`]), its `uniform` a field of the GPU engine's `LevelUniforms`, the
///   level's own parameter buffer;
/// - `kernels`, `key_kernels`: a pipeline of the GPU engine with bind groups and passes of
///   its own (its `bind_groups.rs`, and `steps.rs` or `single_steps.rs`);
/// - `elsewhere`, `key_elsewhere`, `scan`: `name: Shape(uniform)`, a kernel outside the
///   dense pipeline that its caller (the renderer, scan registration) binds over a pool of
///   its own ([`Shape::bound_by_caller`]) and runs in the order of its plan
///   (`crate::plan::render`, `crate::plan::scan_correspondences`): on the GPU through
///   `wgslam_gpu::row_kernels`, on the CPU through
///   [`run_call`](crate::cpu_backend::run_call); `scan`'s are prefixed with
///   `shaders/scan_common.wgsl` instead of `common.wgsl` ([`SCAN_KERNELS`]).
macro_rules! registry_data {
    (
        generic: { $($generic:ident: $shape:ident($uniform:ident) $($bound:ident)?,)* }
        generic_keys: {
            $($generic_key:ident: $key_shape:ident($key_uniform:ident) $($key_bound:ident)?,)*
        }
        generic_levels: {
            $($level:ident: $level_shape:ident($level_uniform:ident) $($level_bound:ident)?,)*
        }
        kernels: { $($kernel:ident,)* }
        key_kernels: { $($key:ident,)* }
        elsewhere: {
            $($other:ident: $other_shape:ident($other_uniform:ident) $($other_bound:ident)?,)*
        }
        key_elsewhere: {
            $($other_key:ident: $okey_shape:ident($okey_uniform:ident) $($other_key_bound:ident)?,)*
        }
        scan: { $($scan:ident: $scan_shape:ident($scan_uniform:ident) $($scan_bound:ident)?,)* }
    ) => {
        /// Every kernel of the registry, one variant per row, named as its shader and its
        /// twin are (hence snake case). Plan calls name kernels by it.
        #[allow(non_camel_case_types)]
        #[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
        pub enum KernelId {
            $($generic,)*
            $($generic_key,)*
            $($level,)*
            $($kernel,)*
            $($key,)*
            $($other,)*
            $($other_key,)*
            $($scan,)*
        }

        impl KernelId {
            /// Every kernel, in the registry's order.
            pub const ALL: &[KernelId] = &[
                $(KernelId::$generic,)*
                $(KernelId::$generic_key,)*
                $(KernelId::$level,)*
                $(KernelId::$kernel,)*
                $(KernelId::$key,)*
                $(KernelId::$other,)*
                $(KernelId::$other_key,)*
                $(KernelId::$scan,)*
            ];

            /// Whether the row is a key kernel's (64-bit keys, with a portable variant
            /// in [`PORTABLE_KERNELS`]): the `generic_keys`, `key_kernels` and
            /// `key_elsewhere` rows.
            pub const fn is_key(self) -> bool {
                match self {
                    $(KernelId::$generic_key => true,)*
                    $(KernelId::$key => true,)*
                    $(KernelId::$other_key => true,)*
                    _ => false,
                }
            }

            /// The kernel's name: its shader `shaders/<name>.wgsl` and its twin
            /// `crate::cpu::<name>::<name>`.
            pub const fn name(self) -> &'static str {
                match self {
                    $(KernelId::$generic => stringify!($generic),)*
                    $(KernelId::$generic_key => stringify!($generic_key),)*
                    $(KernelId::$level => stringify!($level),)*
                    $(KernelId::$kernel => stringify!($kernel),)*
                    $(KernelId::$key => stringify!($key),)*
                    $(KernelId::$other => stringify!($other),)*
                    $(KernelId::$other_key => stringify!($other_key),)*
                    $(KernelId::$scan => stringify!($scan),)*
                }
            }

            /// The [`Shape`] of a row's kernel (a `generic` row's, or one its caller binds:
            /// the `elsewhere` and `scan` groups'), `None` for another row's.
            pub const fn shape(self) -> Option<Shape> {
                match self {
                    $(KernelId::$generic => Some(Shape::$shape),)*
                    $(KernelId::$generic_key => Some(Shape::$key_shape),)*
                    $(KernelId::$level => Some(Shape::$level_shape),)*
                    $(KernelId::$other => Some(Shape::$other_shape),)*
                    $(KernelId::$other_key => Some(Shape::$okey_shape),)*
                    $(KernelId::$scan => Some(Shape::$scan_shape),)*
                    // The rows with bind groups of their own.
                    $(KernelId::$kernel => None,)*
                    $(KernelId::$key => None,)*
                }
            }

            /// The name of a row's uniform, bound as the kernel's `params` (on the GPU a
            /// field of `Uniforms` or `LevelUniforms`, or for a row its caller binds the
            /// caller's pool's resource of that name; in the CPU engine's
            /// [`Pool`](crate::cpu::binding::Pool) a uniform of that name).
            pub const fn uniform(self) -> Option<&'static str> {
                match self {
                    $(KernelId::$generic => Some(stringify!($uniform)),)*
                    $(KernelId::$generic_key => Some(stringify!($key_uniform)),)*
                    $(KernelId::$level => Some(stringify!($level_uniform)),)*
                    $(KernelId::$other => Some(stringify!($other_uniform)),)*
                    $(KernelId::$other_key => Some(stringify!($okey_uniform)),)*
                    $(KernelId::$scan => Some(stringify!($scan_uniform)),)*
                    // The rows with bind groups of their own.
                    $(KernelId::$kernel => None,)*
                    $(KernelId::$key => None,)*
                }
            }

            /// The twin of a `bound` row: `crate::cpu::<name>::<name>` in the one call
            /// shape, with the bindings it takes (`crate::cpu::binding`). Every row is
            /// `bound`; `None` would be a row added without the marker, which
            /// `tests/it/bindings.rs` refuses.
            pub fn twin(self) -> Option<Twin> {
                match self {
                    $(KernelId::$generic => twin_of!($generic $($bound)?),)*
                    $(KernelId::$generic_key => twin_of!($generic_key $($key_bound)?),)*
                    $(KernelId::$level => twin_of!($level $($level_bound)?),)*
                    $(KernelId::$other => twin_of!($other $($other_bound)?),)*
                    $(KernelId::$other_key => twin_of!($other_key $($other_key_bound)?),)*
                    $(KernelId::$scan => twin_of!($scan $($scan_bound)?),)*
                }
            }
        }

        /// Every kernel the GPU engine builds as `(name, text of shaders/<file_of(name)>.wgsl)`:
        /// one row per file, plus one per portable variant of a key kernel (the same text).
        /// `tests/it/shaders.rs` fails when a `.wgsl` file is missing here.
        pub const KERNELS: &[(&str, &str)] = &[
            $((stringify!($generic), shader_text!($generic)),)*
            $((stringify!($generic_key), shader_text!($generic_key)),)*
            $((stringify!($level), shader_text!($level)),)*
            $((stringify!($kernel), shader_text!($kernel)),)*
            $((stringify!($key), shader_text!($key)),)*
            $((stringify!($other), shader_text!($other)),)*
            $((stringify!($other_key), shader_text!($other_key)),)*
            $((stringify!($scan), shader_text!($scan)),)*
            $((concat!(stringify!($generic_key), "_portable"), shader_text!($generic_key)),)*
            $((concat!(stringify!($key), "_portable"), shader_text!($key)),)*
            $((concat!(stringify!($other_key), "_portable"), shader_text!($other_key)),)*
        ];
        /// The key kernels (the registry's `key` groups), each built in two variants from
        /// its one file `shaders/<kernel>.wgsl` followed by `shaders/key_writer.wgsl`:
        /// `(kernel, portable)`. The kernel (the file with `KEY_64` defined) keeps the
        /// nearest surfel per pixel with one 64-bit `atomicMax` and needs `SHADER_INT64`
        /// and `SHADER_INT64_ATOMIC_MIN_MAX`; its portable variant (the same file without
        /// `KEY_64`) keeps the same 64-bit key as two u32 words, (low = index, high = depth
        /// word), in two dispatches over the same bind groups (its `override KEY_PASS`: 0
        /// then 1), and decides the same winner bit for bit. Every other kernel, portable
        /// variants included, validates without 64-bit integers (`tests/it/shaders.rs`).
        /// The CPU twin `crates/core/src/cpu/<kernel>.rs` serves both, through its key maps
        /// (`cpu::key_writer::KeyMap` parameters: the 64-bit keys or a portable pass).
        pub const PORTABLE_KERNELS: &[(&str, &str)] = &[
            $((stringify!($generic_key), concat!(stringify!($generic_key), "_portable")),)*
            $((stringify!($key), concat!(stringify!($key), "_portable")),)*
            $((stringify!($other_key), concat!(stringify!($other_key), "_portable")),)*
        ];

        /// The kernels bound and dispatched by their rows alone: the `generic` rows', and
        /// those of the rows their callers bind over pools of their own (the `elsewhere`
        /// and `scan` groups: [`Shape::bound_by_caller`]); `tests/it/kernel_places.rs`
        /// checks that nothing else in the engine names them.
        pub const GENERIC_KERNELS: &[&str] = &[
            $(stringify!($generic),)*
            $(stringify!($generic_key),)*
            $(stringify!($level),)*
            $(stringify!($other),)*
            $(stringify!($other_key),)*
            $(stringify!($scan),)*
        ];

        /// The kernels prefixed with `scan_common.wgsl` instead of `common.wgsl` (the
        /// registry's `scan` group).
        pub const SCAN_KERNELS: &[&str] = &[$(stringify!($scan),)*];

        /// Each row's CPU twin, `crate::cpu::<name>::<name>`: this does not compile when
        /// one is missing.
        #[allow(unused_imports)]
        mod twins {
            $(use crate::cpu::$generic::$generic as _;)*
            $(use crate::cpu::$generic_key::$generic_key as _;)*
            $(use crate::cpu::$level::$level as _;)*
            $(use crate::cpu::$kernel::$kernel as _;)*
            $(use crate::cpu::$key::$key as _;)*
            $(use crate::cpu::$other::$other as _;)*
            $(use crate::cpu::$other_key::$other_key as _;)*
            $(use crate::cpu::$scan::$scan as _;)*
        }

        /// Calls `registry_pipelines!` (in scope where this is called: see
        /// `wgslam_gpu::pipelines`) with the rows the GPU engine's pipelines are built from.
        #[macro_export]
        macro_rules! pipeline_rows {
            () => {
                registry_pipelines! {
                    generic: { $($generic: $shape($uniform),)* }
                    generic_keys: { $($generic_key: $key_shape($key_uniform),)* }
                    kernels: { $($kernel,)* }
                    key_kernels: { $($key,)* }
                    generic_levels: { $($level: $level_shape($level_uniform),)* }
                }
            };
        }
    };
}

registry_data! {
    generic: {
        depth_to_vertex: OverFrame(preprocess) bound,
        bilateral_filter: OverFrame(bilateral) bound,
        predict_model: PerChunk(project) bound,
        fuse_merge_chosen: PerChunk(fuse) bound,
        fuse_prune: PerBlock(fuse) bound,
        fuse_merge: PerBlock(fuse) bound,
        fuse_flags: OverFrame(fuse) bound,
        // The culling blocks' boxes (`block_boxes`) where they are stale: the first
        // call of every culling step.
        block_bounds: PerStaleBlock(bounds) bound,
        // ICP's and RGB-D tracking's systems at a pyramid level: the geometric and the
        // photometric term's rows into per-workgroup partial systems, and their sum
        // (`icp_reduce_final` declares no `params`: its row's uniform, the reductions', is
        // offered to its bind groups and not taken). The CPU's partials and sum are f64
        // (`cpu::icp_reduce`'s notes).
        icp_reduce: Reduce(icp) bound,
        photo_reduce: Reduce(icp) bound,
        icp_reduce_final: PerSystem(icp) bound,
        // Loop closure's map deformation: every live surfel moved by the pose graph's
        // corrections (`nodes`, the node table).
        deform_surfels: PerSurfel(deform) bound,
        // Compaction's keep flag per surfel (its `flags`, one per map slot).
        compact_flags: PerSurfel(compact) bound,
        // Compaction's copy of the survivors into the spare map (one surfel array at a
        // time keeps it within WebGPU's 8 storage buffers per stage).
        compact_scatter: PerChunkPair(compact) bound,
        // The scan's three kernels (fusion's over its new-surfel flags, compaction's over
        // its keep flags): block sums, their scan, each block's scan.
        prefix_sum_reduce: PerScanBlock(scan) bound,
        prefix_sum_blocks: OneWorkgroup(scan) bound,
        prefix_sum: PerScanBlock(scan) bound,
        // Relocalisation's: the frame's fern codes (`ferns` in, `codes` out), its corners
        // (`keypoints`, `counter`) and their descriptors (`pattern`, `descriptors`,
        // `points`).
        fern_encode: PerItem(ferns) bound,
        keypoint_detect: OverFrame(keypoints) bound,
        keypoint_describe: PerItem(keypoints) bound,
        // Tracking health's: per workgroup, the pixels with an ICP candidate at level 0
        // (`counts`, summed on the host).
        icp_candidates: PerCount(icp) bound,
    }
    generic_keys: {
        // The map's depth keys at the predicted view, and fusion's choice of surfel per
        // pixel (best-candidate association).
        project_model: PerBlock(project) bound,
        fuse_select: PerBlock(fuse) bound,
        // Fusion's new surfels, per map chunk the ones whose slots it holds (its later
        // passes as the plan call says: `Call::every_key_pass`).
        fuse_add: PerChunk(fuse) bound,
    }
    generic_levels: {
        // The frame's normals per level (at level 0 from the vertex maps the plan
        // chooses), and the frame's and the model's coarser levels.
        vertex_to_normal: PerLevel(normal) bound,
        pyramid_depth: PerLevel(pyramid) bound,
        pyramid_model: PerLevel(pyramid) bound,
        // The frame's intensity pyramid (RGB-D tracking), each level from the finer one's
        // (level 0 from the colour map), made as the photometric term first reads it.
        intensity_pyramid: PerLevel(intensity) bound,
    }
    kernels: {}
    key_kernels: {}
    elsewhere: {
        // Pictures of the map (src/render/), not part of the SLAM pipeline: each pixel's
        // colour from the splatted keys (planned by `plan::render`).
        render_resolve: PerPoint(render) bound,
    }
    key_elsewhere: {
        // The nearest surfel's key per pixel (`index_map`), one thread per surfel.
        render_splat: PerPoint(render) bound,
    }
    scan: {
        // Scan registration (point-to-point ICP, src/scan/), planned by
        // `plan::scan_correspondences`: each query's nearest target point, by brute force
        // (per range of targets) or through the hashed grid, and the inlier pairs'
        // cross-covariance as per-workgroup partials.
        nn_brute: PerPoint(neighbours) bound,
        nn_grid: PerPoint(neighbours) bound,
        cross_covariance: PerPartial(covariance) bound,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A row is a key kernel's exactly when its kernel has a portable variant: the typed
    /// test the engines use and the list the shaders are built from say the same.
    #[test]
    fn key_rows_are_the_kernels_with_a_portable_variant() {
        let keys: Vec<&str> = KernelId::ALL
            .iter()
            .filter(|id| id.is_key())
            .map(|id| id.name())
            .collect();
        let portable: Vec<&str> = PORTABLE_KERNELS.iter().map(|(k, _)| *k).collect();
        assert_eq!(keys, portable);
        assert!(keys.contains(&"render_splat") && keys.contains(&"fuse_select"));
    }
}
