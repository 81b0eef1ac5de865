// key_writer.wgsl: how a key kernel's pixel keeps the larger of its key and a surfel's, in
// both variants. Not a kernel: crates/gpu/src/shaders.rs appends it to each key kernel
// (project_model, fuse_select, fuse_add, render_splat) after the kernel's own text, with
// KEY_64 defined or not, so every key kernel writes its `index_map` with this one code.
// Mirrors crates/core/src/cpu/key_writer.rs (`KeyWriter`: `[u64]` for KEY_64, `KeyPass` without).
//
// A key is (high, index): high a depth word (depth_key, larger = nearer), index a map-wide
// surfel index, compared as the u64 (high << 32) | index; ties go to the larger index and
// 0 means no surfel. The kernel declares `index_map` as one atomic<u64> per pixel with
// KEY_64, else as two atomic<u32> words per pixel, (low = index, high), the little-endian
// layout of the u64, cleared to 0 by the host before pass 0.

#ifdef KEY_64
// The pixel `pix` keeps the larger of its key and (high, index): one atomicMax. Needs
// SHADER_INT64_ATOMIC_MIN_MAX.
fn keep_nearer(pix: u32, high: u32, index: u32) {
    atomicMax(&index_map[pix], (u64(high) << 32u) | u64(index));
}

// Whether this dispatch writes what the kernel writes besides keys: always (one pass).
fn first_key_pass() -> bool {
    return true;
}
#else
// Which word this dispatch decides: 0 the high word, 1 the index word. Pass 0 runs over
// every chunk before pass 1 (both over the same bind groups).
override KEY_PASS: u32;

// Pass KEY_PASS of the two-pass maximum of the key (high, index) at pixel `pix`: pass 0
// raises the high word; pass 1 raises the index word if this surfel's high word is the
// pixel's (pass 1 recomputes the same high word from the same inputs). After both, the
// pair is the u64 maximum bit for bit. Mirrors `cpu::keep_nearer`.
fn keep_nearer(pix: u32, high: u32, index: u32) {
    if KEY_PASS == 0u {
        atomicMax(&index_map[2u * pix + 1u], high);
    } else if atomicLoad(&index_map[2u * pix + 1u]) == high {
        atomicMax(&index_map[2u * pix], index);
    }
}

// Whether this dispatch writes what the kernel writes besides keys: pass 0 only.
fn first_key_pass() -> bool {
    return KEY_PASS == 0u;
}
#endif
