//! How the twins spread a kernel's invocations over the machine's cores (rayon), as a GPU
//! spreads them over its lanes: the per-invocation body is the shader's, only the
//! distribution is here. Not a kernel twin of its own.
//!
//! The rule that keeps the CPU reference deterministic for any number of threads:
//! - an invocation writes only what no other invocation writes or reads ([`Storage`]:
//!   a storage buffer, one element per invocation or per slot the kernel's own indices
//!   keep apart), or raises a key through an order-independent maximum
//!   (`key_writer`'s atomic `keep_nearer`: [`atomic_keys`], [`atomic_words`]);
//! - a reduction sums fixed-size runs of its invocations in parallel, each in invocation
//!   order, then the partial sums in their order ([`par_sum_rows`]), so its sum's bits do not
//!   depend on the number of threads;
//! - an append through a counter, or a loop whose result depends on the order of its
//!   invocations, stays sequential.
//!
//! Threads come from the rayon pool the caller runs in (`CpuBackend` installs its own
//! around its steps when `--threads` bounds it; otherwise rayon's global pool, one thread
//! per core). On a thread where `arith` left the exact mode (its test modes and planted
//! bugs are per thread, and its perturbed sums are sequential), every loop here runs in
//! order on the calling thread instead.

use std::marker::PhantomData;
use std::num::NonZeroUsize;
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering};
use std::sync::Arc;

use bytemuck::Pod;
use rayon::prelude::*;

/// Invocations per rayon task: a 640x480 image is 75 tasks, enough to balance two to
/// sixteen cores, each long enough (tens of microseconds) to repay its scheduling.
pub const INVOCATIONS_PER_TASK: usize = 4096;

/// Invocations per partial sum of [`par_sum_rows`]: fixed, so that the partials (and the
/// sum's bits) do not depend on the number of threads; a 640x480 image makes 75.
pub const ROWS_PER_PARTIAL: usize = INVOCATIONS_PER_TASK;

/// True when this thread must run a twin's invocations itself, in order (see the module
/// notes).
#[inline]
fn in_order_here() -> bool {
    super::arith::engaged_here()
}

/// `body(i)` for every invocation `i` in `0..n`, in parallel on the current rayon pool in
/// tasks of [`INVOCATIONS_PER_TASK`]; in order on this thread where `arith` says so. The
/// body may write only through [`Storage`] (or atomics) at indices no other invocation
/// touches, as a shader invocation may.
pub fn par_for_each_invocation(n: usize, body: impl Fn(usize) + Sync + Send) {
    if in_order_here() {
        (0..n).for_each(body);
        return;
    }
    (0..n)
        .into_par_iter()
        .with_min_len(INVOCATIONS_PER_TASK)
        .for_each(body);
}

/// `body(g)` for every workgroup `g` in `0..groups` of a kernel whose workgroups hold
/// `invocations_per_group` invocations each (the body runs a group's invocations, as
/// `visible_surfels` runs a culling block's surfels), in parallel in tasks of about
/// [`INVOCATIONS_PER_TASK`] invocations; in order on this thread where `arith` says so.
/// The body writes as [`par_for_each_invocation`]'s may.
pub fn par_for_each_group(
    groups: usize,
    invocations_per_group: usize,
    body: impl Fn(usize) + Sync + Send,
) {
    if in_order_here() {
        (0..groups).for_each(body);
        return;
    }
    let per_task = (INVOCATIONS_PER_TASK / invocations_per_group.max(1)).max(1);
    (0..groups)
        .into_par_iter()
        .with_min_len(per_task)
        .for_each(body);
}

/// `data` as `n` copies of `value` (a buffer cleared before a step, as the GPU clears
/// one), written in parallel in tasks of [`INVOCATIONS_PER_TASK`]; in order on this thread
/// where `arith` says so. Only a change of length allocates.
pub fn par_fill<T: Copy + Send + Sync>(data: &mut Vec<T>, n: usize, value: T) {
    data.truncate(n);
    let kept = data.len();
    data.resize(n, value);
    let old = &mut data[..kept];
    if in_order_here() {
        old.fill(value);
        return;
    }
    old.par_chunks_mut(INVOCATIONS_PER_TASK)
        .for_each(|chunk| chunk.fill(value));
}

/// `data` as atomic words that invocations on many threads may raise or write (relaxed):
/// the CPU side of a WGSL `array<atomic<u32>>`, held for as long as the borrow of `data`.
pub fn atomic_words(data: &mut [u32]) -> &[AtomicU32] {
    // SAFETY: `AtomicU32` has the size and alignment of `u32` (documented), and the
    // exclusive borrow of `data` is held for the view's lifetime, so nothing reads or writes
    // these words except through the atomics while it lives.
    unsafe { &*(data as *mut [u32] as *const [AtomicU32]) }
}

// `atomic_keys` below relies on this; it holds on every target wgslam builds for (x86-64,
// AArch64, wasm32), and a target where it does not fails to compile here.
const _: () = assert!(std::mem::align_of::<u64>() == std::mem::align_of::<AtomicU64>());

/// `data` as atomic 64-bit keys (the CPU side of a WGSL `array<atomic<u64>>`; see
/// [`atomic_words`]).
pub fn atomic_keys(data: &mut [u64]) -> &[AtomicU64] {
    // SAFETY: `AtomicU64` has the size of `u64` and, checked above, its alignment; the
    // exclusive borrow is held as in `atomic_words`.
    unsafe { &*(data as *mut [u64] as *const [AtomicU64]) }
}

/// A reduction's invocations: `add_row(partial, i)` for every `i` in `0..n`, into partials
/// of [`ROWS_PER_PARTIAL`] consecutive invocations each, made in parallel (each from
/// `zero()`, in increasing `i`), then `add_partial(total, partial)` on this thread in the
/// partials' order. The partials do not depend on the number of threads, so neither does
/// the sum's every bit (a GPU sums per workgroup as well). Where `arith` says so, every row
/// goes in order on this thread into one sum instead (its perturbed sums need one).
pub fn par_sum_rows<S: Send>(
    n: usize,
    zero: impl Fn() -> S + Sync + Send,
    add_row: impl Fn(&mut S, usize) + Sync + Send,
    mut add_partial: impl FnMut(&mut S, S),
) -> S {
    let mut total = zero();
    if in_order_here() {
        (0..n).for_each(|i| add_row(&mut total, i));
        return total;
    }
    let partials: Vec<S> = (0..n.div_ceil(ROWS_PER_PARTIAL))
        .into_par_iter()
        .map(|c| {
            let mut partial = zero();
            (c * ROWS_PER_PARTIAL..n.min((c + 1) * ROWS_PER_PARTIAL))
                .for_each(|i| add_row(&mut partial, i));
            partial
        })
        .collect();
    partials
        .into_iter()
        .for_each(|p| add_partial(&mut total, p));
    total
}

/// The threads a CPU backend's twins run on: rayon's global pool (one thread per core,
/// the default) or a pool of its own of `--threads N` (a batch running jobs at once gives
/// each a share of the cores). Clones share the pool.
#[derive(Debug, Clone, Default)]
pub struct Threads(Option<Arc<rayon::ThreadPool>>);

impl Threads {
    /// A pool of its own of `n` threads.
    pub fn bounded(n: NonZeroUsize) -> crate::Result<Threads> {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(n.get())
            .thread_name(|i| format!("wgslam-cpu-{i}"))
            .build()
            .map_err(|e| crate::Error::Argument(format!("cannot start {n} CPU threads: {e}")))?;
        Ok(Threads(Some(Arc::new(pool))))
    }

    /// Threads the twins may use.
    pub fn count(&self) -> usize {
        match &self.0 {
            Some(pool) => pool.current_num_threads(),
            None => rayon::current_num_threads(),
        }
    }

    /// Runs `f` (a backend step) with its twins on these threads. On a thread where `arith`
    /// left the exact mode, `f` runs here (its twins in order; see the module notes).
    pub fn install<R: Send>(&self, f: impl FnOnce() -> R + Send) -> R {
        match &self.0 {
            Some(pool) if !in_order_here() => pool.install(f),
            _ => f(),
        }
    }
}

/// A storage array that many invocations write at once, each its own elements: the CPU
/// side of a WGSL `var<storage, read_write>` array. Elements are stored as relaxed atomic
/// 32-bit words, so two invocations that broke the rule and wrote one element would leave
/// some mix of their words (as on a GPU), never undefined behaviour.
pub struct Storage<'a, T> {
    words: &'a [AtomicU32],
    element: PhantomData<&'a mut [T]>,
}

impl<'a, T: Pod> Storage<'a, T> {
    /// Words per element.
    const WORDS: usize = std::mem::size_of::<T>() / 4;

    /// A view of `data` that invocations on many threads write (`T`: a whole number of
    /// 32-bit words, aligned to at least 4 bytes).
    pub fn new(data: &'a mut [T]) -> Self {
        assert!(
            std::mem::size_of::<T>() % 4 == 0 && std::mem::align_of::<T>() >= 4,
            "Storage: elements must be whole 32-bit words"
        );
        let words = atomic_words(bytemuck::cast_slice_mut(data));
        Storage {
            words,
            element: PhantomData,
        }
    }

    /// Elements in the array.
    pub fn len(&self) -> usize {
        self.words.len() / Self::WORDS
    }

    /// True when the array holds no element.
    pub fn is_empty(&self) -> bool {
        self.words.is_empty()
    }

    /// Writes element `i`.
    #[inline]
    pub fn store(&self, i: usize, value: T) {
        let w = &self.words[i * Self::WORDS..(i + 1) * Self::WORDS];
        for (word, &bits) in w.iter().zip(bytemuck::cast_slice::<T, u32>(&[value])) {
            word.store(bits, Ordering::Relaxed);
        }
    }

    /// Reads element `i`.
    #[inline]
    pub fn load(&self, i: usize) -> T {
        let mut value = T::zeroed();
        let w = &self.words[i * Self::WORDS..(i + 1) * Self::WORDS];
        for (bits, word) in bytemuck::cast_slice_mut::<T, u32>(std::slice::from_mut(&mut value))
            .iter_mut()
            .zip(w)
        {
            *bits = word.load(Ordering::Relaxed);
        }
        value
    }
}

impl Storage<'_, u32> {
    /// `atomicMin(&array[i], value)`: order-independent, so any number of invocations may
    /// lower one element.
    #[inline]
    pub fn fetch_min(&self, i: usize, value: u32) {
        self.words[i].fetch_min(value, Ordering::Relaxed);
    }

    /// `atomicMax(&array[i], value)` (see [`Storage::fetch_min`]).
    #[inline]
    pub fn fetch_max(&self, i: usize, value: u32) {
        self.words[i].fetch_max(value, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The rows are summed in fixed partials whatever the pool: the same bits on 1, 2 and 3
    /// threads, those of the partials' sequential sums summed in order, and every row once.
    #[test]
    fn rows_are_summed_in_the_same_partials_on_any_pool() {
        let n = 3 * ROWS_PER_PARTIAL + 17;
        let row = |i: usize| (i as f64 * 0.1).sin();
        let sum_on = |threads| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                let (s, rows) = par_sum_rows(
                    n,
                    || (0.0f64, 0usize),
                    |(s, rows), i| {
                        *s += row(i);
                        *rows += 1;
                    },
                    |(s, rows), (p, p_rows)| {
                        *s += p;
                        *rows += p_rows;
                    },
                );
                assert_eq!(rows, n);
                s
            })
        };
        let mut expected = 0.0f64;
        for c in 0..n.div_ceil(ROWS_PER_PARTIAL) {
            let end = n.min((c + 1) * ROWS_PER_PARTIAL);
            expected += (c * ROWS_PER_PARTIAL..end).map(row).fold(0.0, |s, r| s + r);
        }
        for threads in [1, 2, 3] {
            assert_eq!(
                sum_on(threads).to_bits(),
                expected.to_bits(),
                "{threads} threads"
            );
        }
    }

    /// Every invocation runs once and writes its own element.
    #[test]
    fn each_invocation_writes_its_element() {
        let mut out = vec![[0.0f32; 4]; 10_000];
        let s = Storage::new(&mut out);
        par_for_each_invocation(s.len(), |i| s.store(i, [i as f32, 1.0, 2.0, 3.0]));
        assert_eq!(s.load(9_999), [9_999.0, 1.0, 2.0, 3.0]);
        assert!(out.iter().enumerate().all(|(i, v)| v[0] == i as f32));
    }
}
