// How the WebAssembly module waits for the GPU and for files (crates/gpu/src/wait.rs): it
// imports `suspend` and `wake` from the module "wgslam_suspend" (this file, through the
// page's import map). Rust calls `suspend` while a future is pending and the future's
// waker calls `wake`; meanwhile the event loop runs, so WebGPU's callbacks and file reads
// settle. The page calls every entry point that may wait through `call` below. Two ways,
// one chosen by `choose` before the module is instantiated:
//
// - "jspi" (JavaScript Promise Integration, Chromium 137 or later): `suspend` is a
//   `WebAssembly.Suspending` function whose promise `wake` resolves, and `call` enters
//   through `WebAssembly.promising`; the browser keeps the suspended stack.
// - "asyncify" (every other browser): the page loads pkg/wgslam_bg.asyncify.wasm, the same
//   module rewritten by Binaryen's `wasm-opt --asyncify` (deploy/web/build.sh). `suspend`
//   starts an unwind: every function on the stack saves its locals into STACK_BYTES of the
//   module's memory (wgslam_suspend_stack) and returns, up to the entry point. `call` then
//   awaits `wake`, starts a rewind and calls the entry point again with the same arguments:
//   the functions restore their locals and run back into `suspend`, which ends the rewind
//   and returns to where Rust left off.

// Room for a suspended stack's locals in the asyncify build. The deepest suspension of a
// run over 7-Scenes frames saved 1,484 bytes (deploy/web/test.sh, 2026-11-29); a stack
// that outgrew the room would trap with "unreachable", so it is generous.
const STACK_BYTES = 1 << 20;

// asyncify_get_state's values.
const UNWINDING = 1;
const REWINDING = 2;

let mode = null;
let module = null; // the instance's exports (asyncify)
let stack = 0; // the address of the asyncify buffer in the module's memory
let resume = null;
// How many times the module waited for the event loop (the page shows it), and the most
// bytes of saved locals one asyncify suspension took (0 with JSPI).
globalThis.wgslamSuspensions = 0;
globalThis.wgslamStackBytesMax = 0;

// Whether this browser has JSPI.
export const hasJspi =
  typeof WebAssembly.promising === "function" && typeof WebAssembly.Suspending === "function";

// Chooses "jspi" or "asyncify" (before the module is instantiated: its `suspend` import is
// read then); returns the file name of the module to load from pkg/.
export function choose(wanted) {
  if (wanted === "jspi" && !hasJspi) throw new Error("this browser lacks JSPI");
  mode = wanted;
  suspend = mode === "jspi" ? new WebAssembly.Suspending(suspended) : unwind;
  return mode === "jspi" ? "wgslam_bg.wasm" : "wgslam_bg.asyncify.wasm";
}

// After instantiation: the instance's exports (asyncify needs them to unwind and rewind).
export function attach(exports) {
  module = exports;
  if (mode === "asyncify") {
    stack = exports.wgslam_suspend_stack(STACK_BYTES);
    if (!stack) throw new Error("the module gave no room for its suspended stack");
  }
}

// A promise that `wake` resolves.
function suspended() {
  globalThis.wgslamSuspensions += 1;
  return new Promise((resolve) => {
    resume = resolve;
  });
}

let waiting = null;

// asyncify's `suspend`: at the end of a rewind, return where Rust left off; else unwind.
function unwind() {
  if (module.asyncify_get_state() === REWINDING) {
    module.asyncify_stop_rewind();
    return;
  }
  // The buffer's header: where the saved locals go next, and where the room ends.
  const header = new Int32Array(module.memory.buffer, stack, 2);
  header[0] = stack + 8;
  header[1] = stack + STACK_BYTES;
  waiting = suspended();
  module.asyncify_start_unwind(stack);
}

// The module's `suspend` import (set by `choose`).
export let suspend = () => {
  throw new Error("suspend.js: choose() was not called before the module was instantiated");
};

export function wake() {
  const r = resume;
  resume = null;
  if (r) r();
}

// Calls the module's entry point `entry` (a plain export) with `args`, letting it suspend;
// resolves to its return value.
export async function call(entry, ...args) {
  if (mode === "jspi") return WebAssembly.promising(entry)(...args);
  let result = entry(...args);
  while (module.asyncify_get_state() === UNWINDING) {
    module.asyncify_stop_unwind();
    const used = new Int32Array(module.memory.buffer, stack, 1)[0] - (stack + 8);
    globalThis.wgslamStackBytesMax = Math.max(globalThis.wgslamStackBytesMax, used);
    await waiting;
    module.asyncify_start_rewind(stack);
    result = entry(...args);
  }
  return result;
}
