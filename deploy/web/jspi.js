// JavaScript Promise Integration (JSPI) for crates/gpu/src/wait.rs: the WebAssembly module imports
// `suspend` and `wake` from the module "wgslam_jspi" (this file, through the page's import
// map). Rust calls `suspend` when a GPU future is pending: as a `WebAssembly.Suspending`
// import it suspends the whole WebAssembly stack (which must have been entered through
// `WebAssembly.promising`) until the promise it returned settles, and the event loop runs
// meanwhile, so WebGPU's callbacks fire. The future's waker calls `wake`, which settles it.

let resume = null;
// How many times the module waited for the event loop (the page shows it).
globalThis.wgslamSuspensions = 0;

export const suspend = new WebAssembly.Suspending(
  () =>
    new Promise((resolve) => {
      globalThis.wgslamSuspensions += 1;
      resume = resolve;
    }),
);

export function wake() {
  const r = resume;
  resume = null;
  if (r) r();
}
