//! The key writers of the key kernels' CPU twins (`project_model`, `fuse_select`,
//! `fuse_add`, `render_splat`): how a pixel keeps the larger of its key and a surfel's. CPU
//! twin of `shaders/key_writer.wgsl`, which `crates/gpu/src/shaders.rs` appends to each key kernel
//! (it is not a kernel of its own).
//!
//! A key is `(high, index)`: `high` a depth word ([`depth_key`](super::depth_key), larger
//! = nearer), `index` a map-wide surfel index, compared as the 64-bit number
//! [`pack_depth_index`](super::pack_depth_index) makes (ties go to the larger index; 0 = no
//! surfel). Each key twin is one body generic over [`KeyWriter`], as each key kernel is
//! one WGSL source with two variants (`KEY_64` defined or not): a `[u64]` map is the 64-bit
//! kernel (one pass), a [`KeyPass`] the portable one (two passes over `(low, high)` u32
//! words).
//!
//! In the one call shape (`cpu::binding`) a key twin takes each key map as a [`KeyMap`]
//! parameter, which is either, chosen by the binding: a `Binding::ReadWrite` of `u64` keys
//! (the 64-bit kernel's `array<atomic<u64>>`, as the CPU engine binds it) or a
//! `Binding::KeyPass` of words and the pass (the portable variant's `array<atomic<u32>>`
//! and its `override KEY_PASS`). The twin's body is then one body for both, as the
//! shader's is.
//!
//! Keys are raised through atomics (relaxed `fetch_max`, as the shaders' `atomicMax`), so
//! many threads may raise one map at once: the maximum does not depend on their order, and
//! the twins' loops over surfels run in parallel (`cpu::invocations`).

use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};

use super::binding::{Access, Binding, Param};
use super::invocations::{atomic_keys, atomic_words};
use super::keep_nearer;

/// A map of keys, one per pixel, that a key twin raises. Mirrors `keep_nearer` and
/// `first_key_pass` of `shaders/key_writer.wgsl`, whose two variants are the two
/// implementations here.
pub trait KeyWriter {
    /// The number of pixels the map holds a key for.
    fn pixels(&self) -> usize;

    /// Whether this pass writes what the kernel writes besides keys (`fuse_add`'s new
    /// surfels): always for a 64-bit map (one pass), in pass 0 only for a [`KeyPass`].
    fn first_pass(&self) -> bool;

    /// Pixel `pix` keeps the larger of its key and `(high, index)`; for a [`KeyPass`], this
    /// pass's part of it. Any number of threads may call it at once.
    fn keep_nearer(&self, pix: usize, high: u32, index: u32);
}

/// The 64-bit kernel's map: one `u64` key per pixel, one pass (its `atomicMax`).
impl KeyWriter for [AtomicU64] {
    fn pixels(&self) -> usize {
        self.len()
    }

    fn first_pass(&self) -> bool {
        true
    }

    fn keep_nearer(&self, pix: usize, high: u32, index: u32) {
        self[pix].fetch_max(pack_key(high, index), Ordering::Relaxed);
    }
}

/// The portable kernel's map, `(low = index, high)` u32 words per pixel (the little-endian
/// layout of the 64-bit keys), in pass `key_pass` (the kernel's `override KEY_PASS`) of two:
/// pass 0 over every chunk, then pass 1 over every chunk, leave each pair equal to the
/// 64-bit maximum bit for bit ([`keep_nearer`](super::keep_nearer())).
#[derive(Debug)]
pub struct KeyPass<'a> {
    /// `2 * pixels` words, cleared to 0 before pass 0.
    pub words: &'a [AtomicU32],
    /// 0: raise the high words; 1: raise the index words where the high word is the
    /// surfel's.
    pub key_pass: u32,
}

impl<'a> KeyPass<'a> {
    /// Pass `key_pass` (0 or 1) over `words`.
    pub fn new(words: &'a mut [u32], key_pass: u32) -> KeyPass<'a> {
        KeyPass {
            words: atomic_words(words),
            key_pass,
        }
    }
}

impl KeyWriter for KeyPass<'_> {
    fn pixels(&self) -> usize {
        self.words.len() / 2
    }

    fn first_pass(&self) -> bool {
        self.key_pass == 0
    }

    fn keep_nearer(&self, pix: usize, high: u32, index: u32) {
        keep_nearer(self.words, pix, high, index, self.key_pass);
    }
}

/// A key twin's key map parameter (`index_map`, `assoc`) as its binding gives it: the
/// 64-bit kernel's keys, or a pass of the portable variant's (see the module notes).
#[derive(Debug)]
pub enum KeyMap<'a> {
    /// One `u64` key per pixel (`Binding::ReadWrite`).
    Keys(&'a [AtomicU64]),
    /// The portable variant's words in one pass (`Binding::KeyPass`).
    Pass(KeyPass<'a>),
}

impl<'a> KeyMap<'a> {
    /// The 64-bit kernel's map over `keys`.
    pub fn keys(keys: &'a mut [u64]) -> KeyMap<'a> {
        KeyMap::Keys(atomic_keys(keys))
    }
}

impl KeyWriter for KeyMap<'_> {
    fn pixels(&self) -> usize {
        match self {
            KeyMap::Keys(keys) => keys.pixels(),
            KeyMap::Pass(pass) => pass.pixels(),
        }
    }

    fn first_pass(&self) -> bool {
        match self {
            KeyMap::Keys(keys) => keys.first_pass(),
            KeyMap::Pass(pass) => pass.first_pass(),
        }
    }

    fn keep_nearer(&self, pix: usize, high: u32, index: u32) {
        match self {
            KeyMap::Keys(keys) => keys.keep_nearer(pix, high, index),
            KeyMap::Pass(pass) => pass.keep_nearer(pix, high, index),
        }
    }
}

/// A key map is written, in elements of the 64-bit kernel's key (the portable variant's
/// pair of words has its size).
impl<'b> Param<'b> for KeyMap<'b> {
    const ACCESS: Access = Access::ReadWrite;
    const ELEMENT_BYTES: usize = std::mem::size_of::<u64>();
    fn view(binding: &'b mut Binding<'_>) -> Self {
        match binding {
            Binding::ReadWrite(bytes) => KeyMap::Keys(atomic_keys(bytemuck::cast_slice_mut(bytes))),
            Binding::KeyPass(bytes, key_pass) => {
                KeyMap::Pass(KeyPass::new(bytemuck::cast_slice_mut(bytes), *key_pass))
            }
            Binding::Read(_) => panic!("a key map bound read-only"),
        }
    }
}

/// The 64-bit key `(high, index)`; [`pack_depth_index`](super::pack_depth_index) of a depth whose
/// [`depth_key`](super::depth_key) is `high`.
#[inline]
fn pack_key(high: u32, index: u32) -> u64 {
    (high as u64) << 32 | index as u64
}

#[cfg(test)]
mod tests {
    use super::super::{depth_key, pack_depth_index};
    use super::*;

    /// Both writers, fed the same surfels in any order, leave the same keys: the nearest
    /// surfel, ties to the larger index.
    #[test]
    fn both_writers_keep_the_same_keys() {
        let depths_m = [2.0f32, 1.5, 1.5, 3.0, 1.5];
        let surfels: Vec<(usize, u32, u32)> = depths_m
            .iter()
            .enumerate()
            .map(|(i, &z)| (i % 2, depth_key(z), i as u32))
            .collect();
        let mut keys = vec![0u64; 2];
        let map = KeyMap::keys(&mut keys);
        for &(pix, high, index) in surfels.iter().rev() {
            map.keep_nearer(pix, high, index);
        }
        let mut words = vec![0u32; 4];
        for key_pass in 0..2 {
            let pass = KeyPass::new(&mut words, key_pass);
            for &(pix, high, index) in &surfels {
                pass.keep_nearer(pix, high, index);
            }
        }
        assert_eq!(keys, [pack_depth_index(1.5, 4), pack_depth_index(1.5, 1)]);
        let as_keys: Vec<u64> = words.chunks(2).map(|w| pack_key(w[1], w[0])).collect();
        assert_eq!(as_keys, keys);
    }
}
