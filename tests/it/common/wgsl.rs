//! WGSL checked with naga at test time, no GPU: parse and validate a source, reporting a
//! failure with its file and line; and compare a Rust `#[repr(C)]` struct with naga's
//! layout of the WGSL struct of the same name (size, member names, order and offsets).
//! Used by the modules `shaders`, `layout`, `render` and `scan_kernels`.

/// The capabilities the dense-SLAM kernels need (and lavapipe offers): 64-bit integers and
/// 64-bit `atomicMax` for the packed depth + surfel index map.
pub fn kernel_capabilities() -> naga::valid::Capabilities {
    naga::valid::Capabilities::SHADER_INT64 | naga::valid::Capabilities::SHADER_INT64_ATOMIC_MIN_MAX
}

/// Parses and validates `source` with `capabilities`; on failure returns a message that
/// starts `file:line:column` (the source line mapped back to its file through `origin`,
/// for sources concatenated from several files) and names `label`.
pub fn check(
    label: &str,
    source: &str,
    capabilities: naga::valid::Capabilities,
    origin: impl Fn(usize) -> (String, usize),
) -> Option<String> {
    let at = |location: Option<naga::SourceLocation>| {
        location
            .map(|l| {
                let (file, line) = origin(l.line_number as usize);
                format!("{file}:{line}:{}", l.line_position)
            })
            .unwrap_or_else(|| label.to_string())
    };
    let module = match naga::front::wgsl::parse_str(source) {
        Ok(m) => m,
        Err(e) => {
            return Some(format!(
                "{}: parse error in {label}: {}\n{}",
                at(e.location(source)),
                e.message(),
                e.emit_to_string(source)
            ));
        }
    };
    let mut validator =
        naga::valid::Validator::new(naga::valid::ValidationFlags::all(), capabilities);
    validator.validate(&module).err().map(|e| {
        format!(
            "{}: validation error in {label}: {}\n{}",
            at(e.location(source)),
            e.as_inner(),
            e.emit_to_string(source)
        )
    })
}

/// Parses `source` (named `label` in the panic message); panics with naga's report.
pub fn parse(label: &str, source: &str) -> naga::Module {
    naga::front::wgsl::parse_str(source)
        .unwrap_or_else(|e| panic!("{}", e.emit_to_string_with_path(source, label)))
}

/// A Rust struct's layout: name, `size_of`, `(member, offset_of)` in declaration order, and
/// `(member, struct name)` for each member that is itself a shared struct (nested, as
/// `camera: Camera`).
pub struct RustLayout {
    pub name: &'static str,
    pub size: usize,
    pub members: Vec<(&'static str, usize)>,
    pub struct_members: Vec<(&'static str, &'static str)>,
}

/// `rust_layout!(Type { field, field: Nested, ... })`: the [`RustLayout`] of `Type`, listing
/// every field in declaration order (the WGSL struct must have the same members in that
/// order), a field of a nested shared struct with its type (checked here by the compiler,
/// against the WGSL member's struct by [`layout_mismatches`]; the nested struct's own
/// layout has its own entry). (Unused in the test files that include `common` for other
/// helpers.)
#[allow(unused_macros)]
macro_rules! rust_layout {
    ($ty:ident { $($field:ident $(: $nested:ident)?),* $(,)? }) => {
        $crate::common::wgsl::RustLayout {
            name: stringify!($ty),
            size: ::std::mem::size_of::<$ty>(),
            members: vec![$((stringify!($field), ::std::mem::offset_of!($ty, $field))),*],
            struct_members: {
                #[allow(unused_mut)]
                let mut nested: Vec<(&'static str, &'static str)> = Vec::new();
                $($(
                    let _: fn(&$ty) -> &$nested = |s| &s.$field;
                    nested.push((stringify!($field), stringify!($nested)));
                )?)*
                nested
            },
        }
    };
}
#[allow(unused_imports)]
pub(crate) use rust_layout;

/// Compares `rust` with the WGSL struct of the same name in `module` (`label` names the
/// source in messages) and returns one message per mismatch: a missing struct, a size
/// (naga's struct span or its layouter) or member count that differs, a member whose
/// name or offset differs, or a member of struct type whose struct differs from the one
/// `rust` names for it (or that `rust` does not name). With the nested struct's own entry
/// this checks the offset of every field of a nested struct too.
pub fn layout_mismatches(label: &str, module: &naga::Module, rust: &RustLayout) -> Vec<String> {
    let name = rust.name;
    let mut layouter = naga::proc::Layouter::default();
    if let Err(e) = layouter.update(module.to_ctx()) {
        return vec![format!("{label}: naga cannot lay out the module: {e}")];
    }
    let Some((handle, ty)) = module
        .types
        .iter()
        .find(|(_, t)| t.name.as_deref() == Some(name))
    else {
        return vec![format!("{label}: no WGSL struct {name}")];
    };
    let naga::TypeInner::Struct { members, span } = &ty.inner else {
        return vec![format!("{label}: WGSL type {name} is not a struct")];
    };
    let mut failures = Vec::new();
    let wgsl_size = layouter[handle].size as usize;
    if *span as usize != rust.size || wgsl_size != rust.size {
        failures.push(format!(
            "{label}: {name}: Rust size {} bytes, WGSL size {span} (layouter {wgsl_size})",
            rust.size
        ));
    }
    let wgsl_members: Vec<(String, usize)> = members
        .iter()
        .map(|m| (m.name.clone().unwrap_or_default(), m.offset as usize))
        .collect();
    if wgsl_members.len() != rust.members.len() {
        failures.push(format!(
            "{label}: {name}: Rust has {} members, WGSL {}",
            rust.members.len(),
            wgsl_members.len()
        ));
    }
    for ((rn, ro), (wn, wo)) in rust.members.iter().zip(&wgsl_members) {
        if rn != wn || ro != wo {
            failures.push(format!(
                "{label}: {name}: Rust member `{rn}` at offset {ro}, WGSL member `{wn}` at offset {wo}"
            ));
        }
    }
    for m in members {
        let member = m.name.clone().unwrap_or_default();
        let wgsl_struct = match &module.types[m.ty] {
            naga::Type {
                name: Some(n),
                inner: naga::TypeInner::Struct { .. },
            } => Some(n.as_str()),
            _ => None,
        };
        let rust_struct = (rust.struct_members.iter())
            .find(|(f, _)| *f == member)
            .map(|(_, s)| *s);
        if wgsl_struct != rust_struct {
            failures.push(format!(
                "{label}: {name}: member `{member}` is struct {wgsl_struct:?} in WGSL, {rust_struct:?} in Rust"
            ));
        }
    }
    failures
}
