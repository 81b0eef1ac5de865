//! The one call shape of the CPU twins, and the pool their bindings are taken from: the
//! CPU side of the kernel engine (the model is vello's `fn(n_wg, &[CpuBinding])`). Not a
//! kernel twin of its own, and no wgpu.
//!
//! A twin with the shape is a [`TwinFn`], `fn(&mut [Binding])`: the shader's bindings as
//! bytes, in `@binding` order. It is written with `twin!` as a plain function over typed
//! slices, its parameters named as the WGSL variables and in their order:
//!
//! ```text
//! twin! {
//!     /// docs
//!     pub fn pyramid_depth(
//!         params: &PyramidParams,       // var<storage, read> params: PyramidParams
//!         fine_vertex: &[[f32; 4]],     // var fine_vertex: texture_2d<f32>
//!         vertex_map: &mut [[f32; 4]],  // var vertex_map: texture_storage_2d<rgba32float, write>
//!     ) { /* the shader's body, line by line */ }
//! }
//! ```
//!
//! The macro makes the twin `pub fn pyramid_depth(bindings: &mut [Binding])`, which views
//! each binding as its parameter's type and runs the body, and the module's [`BINDINGS`]
//! (one [`Slot`] per parameter: name, [`Access`], element size), which the registry row
//! carries ([`Twin`]). A parameter `&T` is a read-only value (the kernel's `params`), `&[T]`
//! a read-only array or texture, `&mut [T]` a writable one, and a key kernel's key map a
//! [`KeyMap`](super::key_writer::KeyMap) (the 64-bit kernel's `u64` keys, or a
//! [`Binding::KeyPass`] of the portable variant's). `tests/it/bindings.rs` checks
//! every [`BINDINGS`] against the shader's declarations as naga reflects them (names,
//! order, read-only or writable, element size), so a twin that would bind another buffer
//! than its shader fails a test.
//!
//! A backend takes the bindings from a [`Pool`] of its buffers, named as the WGSL
//! variables (as the GPU engine's bind groups are: `wgslam_gpu`'s `bind_groups.rs`), with
//! the kernel's `params` the pool's uniform named by the kernel's registry row
//! ([`Pool::bind`]).
//!
//! [`BINDINGS`]: crate::cpu::depth_to_vertex::BINDINGS

use bytemuck::Pod;

/// How a kernel uses a binding: read only (`var<storage, read>`, `texture_2d`), or
/// written (`var<storage, read_write>`, `texture_storage_2d<_, write>`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    Read,
    ReadWrite,
}

/// One binding a twin takes: the WGSL variable's name, how the kernel uses it, and the
/// bytes of one element (the `params` struct's size, an array's stride, a texel's size).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Slot {
    pub name: &'static str,
    pub access: Access,
    pub element_bytes: usize,
}

/// A binding as a twin receives it: the bytes of the resource the backend bound under the
/// slot's name, shared where the kernel only reads it.
#[derive(Debug)]
pub enum Binding<'a> {
    Read(&'a [u8]),
    ReadWrite(&'a mut [u8]),
    /// A key map of a key kernel's portable variant: its `(low, high)` u32 words, and the
    /// pass (the variant's `override KEY_PASS`, on the GPU a constant of the pipeline, not
    /// of the bind group) its twin runs (`cpu::key_writer::KeyMap`). A [`Pool`] never
    /// makes one: the CPU engine binds a key map as the 64-bit kernel's, a `ReadWrite`.
    KeyPass(&'a mut [u8], u32),
}

impl<'a> Binding<'a> {
    /// A read-only value (a kernel's `params`).
    pub fn of<T: Pod>(value: &'a T) -> Self {
        Binding::Read(bytemuck::bytes_of(value))
    }

    /// A read-only array (or texture, row-major).
    pub fn read<T: Pod>(data: &'a [T]) -> Self {
        Binding::Read(bytemuck::cast_slice(data))
    }

    /// A writable array (or storage texture, row-major).
    pub fn write<T: Pod>(data: &'a mut [T]) -> Self {
        Binding::ReadWrite(bytemuck::cast_slice_mut(data))
    }

    /// The portable variant's key map `words` (two per pixel), in pass `key_pass` (0 or 1)
    /// of two.
    pub fn key_pass(words: &'a mut [u32], key_pass: u32) -> Self {
        Binding::KeyPass(bytemuck::cast_slice_mut(words), key_pass)
    }
}

/// The one call shape of a twin: the kernel's bindings in `@binding` order.
pub type TwinFn = fn(&mut [Binding<'_>]);

/// A registry row's twin: the function, and the bindings it takes in order (the module's
/// `BINDINGS`, made by `twin!` from its parameters).
#[derive(Debug, Clone, Copy)]
pub struct Twin {
    pub run: TwinFn,
    pub bindings: &'static [Slot],
}

/// A twin's parameter type, as `twin!` views a [`Binding`]: `&T` a read-only value,
/// `&[T]` a read-only array, `&mut [T]` a writable one.
pub trait Param<'b>: Sized {
    /// How the kernel uses the binding.
    const ACCESS: Access;
    /// Bytes of one element.
    const ELEMENT_BYTES: usize;
    /// The binding viewed as this type. Panics (an internal contract: the backend bound
    /// by the twin's [`Slot`]s) on a read-only binding for a writable parameter, or bytes
    /// that are not whole, aligned elements.
    fn view(binding: &'b mut Binding<'_>) -> Self;
}

impl<'b, T: Pod> Param<'b> for &'b T {
    const ACCESS: Access = Access::Read;
    const ELEMENT_BYTES: usize = std::mem::size_of::<T>();
    fn view(binding: &'b mut Binding<'_>) -> Self {
        bytemuck::from_bytes(read_bytes(binding))
    }
}

impl<'b, T: Pod> Param<'b> for &'b [T] {
    const ACCESS: Access = Access::Read;
    const ELEMENT_BYTES: usize = std::mem::size_of::<T>();
    fn view(binding: &'b mut Binding<'_>) -> Self {
        bytemuck::cast_slice(read_bytes(binding))
    }
}

impl<'b, T: Pod> Param<'b> for &'b mut [T] {
    const ACCESS: Access = Access::ReadWrite;
    const ELEMENT_BYTES: usize = std::mem::size_of::<T>();
    fn view(binding: &'b mut Binding<'_>) -> Self {
        match binding {
            Binding::ReadWrite(bytes) => bytemuck::cast_slice_mut(bytes),
            Binding::Read(_) => panic!("a writable parameter bound read-only"),
            Binding::KeyPass(..) => panic!("an array parameter bound as a key map"),
        }
    }
}

/// The bytes of `binding`, read only.
fn read_bytes<'b>(binding: &'b mut Binding<'_>) -> &'b [u8] {
    match binding {
        Binding::Read(bytes) => bytes,
        Binding::ReadWrite(bytes) | Binding::KeyPass(bytes, _) => bytes,
    }
}

/// The [`Slot`] of a twin's parameter `name` of type `P` (for `twin!`).
pub const fn slot<'b, P: Param<'b>>(name: &'static str) -> Slot {
    Slot {
        name,
        access: P::ACCESS,
        element_bytes: P::ELEMENT_BYTES,
    }
}

/// `twin! { /// docs  pub fn name(binding: Type, ...) { body } }`: the twin `name` in the
/// one call shape ([`TwinFn`]), and the module's `BINDINGS`, from a function written over
/// typed parameters named as the shader's bindings (see the module notes).
macro_rules! twin {
    (
        $(#[$doc:meta])*
        pub fn $name:ident($($arg:ident: $ty:ty),* $(,)?) $body:block
    ) => {
        /// The bindings the twin takes, in `@binding` order, named as the shader's
        /// variables: its parameters (`tests/it/bindings.rs` checks them against the
        /// shader).
        pub const BINDINGS: &[$crate::cpu::binding::Slot] =
            &[$($crate::cpu::binding::slot::<$ty>(stringify!($arg)),)*];

        $(#[$doc])*
        ///
        /// Called as `fn(&mut [Binding])` (`cpu::binding`): the bindings of [`BINDINGS`],
        /// in order.
        pub fn $name(bindings: &mut [$crate::cpu::binding::Binding<'_>]) {
            let given = bindings.len();
            let [$($arg),*] = bindings else {
                panic!(
                    "{}: {} bindings given, the twin takes {}",
                    stringify!($name),
                    given,
                    BINDINGS.len()
                )
            };
            // `mut` allowed, not needed: key maps are raised through atomics (`&self`).
            $(#[allow(unused_mut)] let mut $arg: $ty = $crate::cpu::binding::Param::view($arg);)*
            $body
        }
    };
}
pub(crate) use twin;

/// A resource of a [`Pool`]: shared where the backend only lends it for reading.
enum Entry<'a> {
    Shared(&'a [u8]),
    Exclusive(&'a mut [u8]),
}

/// A backend's resources by the names the kernels declare them with: buffers (each under
/// one name or more: a level's `vertex_map` may be its `point_map` too), and the uniforms
/// bound as a kernel's `params` by its registry row's name for them. A pool lends each
/// kernel what its [`Slot`]s name ([`Pool::bind`]).
#[derive(Default)]
pub struct Pool<'a> {
    entries: Vec<Entry<'a>>,
    names: Vec<(&'static str, usize)>,
    uniforms: Vec<(&'static str, &'a [u8])>,
}

impl<'a> Pool<'a> {
    /// An empty pool.
    pub fn new() -> Self {
        Self::default()
    }

    /// `data`, lent for reading only, under `name`; its index for [`Pool::alias`].
    pub fn read<T: Pod>(&mut self, name: &'static str, data: &'a [T]) -> usize {
        self.add(name, Entry::Shared(bytemuck::cast_slice(data)))
    }

    /// `data`, lent for reading or writing, under `name`; its index for [`Pool::alias`].
    pub fn write<T: Pod>(&mut self, name: &'static str, data: &'a mut [T]) -> usize {
        self.add(name, Entry::Exclusive(bytemuck::cast_slice_mut(data)))
    }

    /// `data`, lent for reading or writing, under no name yet: its index, to name it with
    /// [`Pool::alias`] (a resource whose names depend on the kernel's place).
    pub fn lend<T: Pod>(&mut self, data: &'a mut [T]) -> usize {
        self.entries
            .push(Entry::Exclusive(bytemuck::cast_slice_mut(data)));
        self.entries.len() - 1
    }

    /// The resource of index `entry` under another `name` too; the name no longer names
    /// what it named before (a pool bound once per surfel array names each in turn).
    pub fn alias(&mut self, name: &'static str, entry: usize) {
        self.names.retain(|&(n, _)| n != name);
        self.names.push((name, entry));
    }

    /// `value` as the uniform `name` (a registry row's uniform: a kernel's `params`).
    pub fn uniform<T: Pod>(&mut self, name: &'static str, value: &'a T) {
        self.uniforms.push((name, bytemuck::bytes_of(value)));
    }

    fn add(&mut self, name: &'static str, entry: Entry<'a>) -> usize {
        self.entries.push(entry);
        self.names.push((name, self.entries.len() - 1));
        self.entries.len() - 1
    }

    /// The bindings of `slots` in order: `params` the uniform `uniform`, every other slot
    /// the resource of its name (a slot a kernel writes lent for writing). Panics (internal
    /// contracts, as the GPU's bind groups would fail validation) on a name the pool does
    /// not hold, a read-only resource a kernel writes, or one resource a kernel writes
    /// under one name and binds under another.
    pub fn bind(&mut self, slots: &[Slot], uniform: &str) -> Vec<Binding<'_>> {
        let mut bound: Vec<Option<Binding<'_>>> = slots.iter().map(|_| None).collect();
        for (i, slot) in slots.iter().enumerate() {
            if slot.name == "params" {
                let bytes = self.uniforms.iter().find(|(n, _)| *n == uniform);
                let (_, bytes) =
                    bytes.unwrap_or_else(|| panic!("no uniform `{uniform}` in the pool"));
                bound[i] = Some(Binding::Read(bytes));
            }
        }
        let entry_of = |name: &str| match self.names.iter().find(|(n, _)| *n == name) {
            Some(&(_, e)) => e,
            None => panic!("no `{name}` in the pool"),
        };
        let wanted: Vec<Option<usize>> = slots
            .iter()
            .map(|s| (s.name != "params").then(|| entry_of(s.name)))
            .collect();
        for (e, entry) in self.entries.iter_mut().enumerate() {
            let users: Vec<usize> = (0..slots.len()).filter(|&i| wanted[i] == Some(e)).collect();
            let writer = users
                .iter()
                .find(|&&i| slots[i].access == Access::ReadWrite);
            match (entry, writer) {
                (_, None) if users.is_empty() => {}
                (Entry::Exclusive(bytes), Some(&i)) => {
                    assert_eq!(
                        users.len(),
                        1,
                        "`{}` is written and bound twice",
                        slots[i].name
                    );
                    bound[i] = Some(Binding::ReadWrite(bytes));
                }
                (Entry::Shared(_), Some(&i)) => panic!("`{}` is read-only", slots[i].name),
                (Entry::Shared(bytes), None) => users
                    .iter()
                    .for_each(|&i| bound[i] = Some(Binding::Read(bytes))),
                (Entry::Exclusive(bytes), None) => {
                    let bytes: &[u8] = bytes;
                    users
                        .iter()
                        .for_each(|&i| bound[i] = Some(Binding::Read(bytes)));
                }
            }
        }
        bound
            .into_iter()
            .map(|b| b.expect("every slot bound"))
            .collect()
    }
}
