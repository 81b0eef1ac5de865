//! Waiting for wgpu's futures and callbacks (adapter and device requests, error-scope pops,
//! buffer maps, submitted work) from synchronous code, on every target.
//!
//! Native: [`block_on`] is `pollster`'s and [`wait_for_submitted`] polls the device until
//! the queue is empty; the thread blocks, as a command-line tool's may.
//!
//! Browser (wasm32): nothing may block. WebGPU settles every future and map callback from
//! the JavaScript event loop, which runs only when WebAssembly returns to it; a thread that
//! blocked or spun would wait for ever. Rather than turn the pipeline and its backend trait
//! async (every step, every read-back), the synchronous code stays as it is and a wait
//! *suspends the WebAssembly stack*: the module imports `suspend` and `wake` from the module
//! `wgslam_suspend` (the page's `deploy/web/suspend.js`). [`block_on`] polls the future and,
//! while it is pending, calls `suspend`; the future's waker calls `wake`. While the stack is
//! suspended the event loop runs, WebGPU's callbacks fire and wake the future, and the stack
//! resumes inside `suspend`, where it left off. The page suspends one of two ways:
//!
//! - JavaScript Promise Integration (JSPI, Chromium 137 or later): `suspend` is a
//!   `WebAssembly.Suspending` function returning a promise that `wake` resolves, and the page
//!   calls the entry points that wait through `WebAssembly.promising`.
//! - Binaryen's asyncify, in every other browser with WebGPU: the page loads a copy of the
//!   module that `wasm-opt --asyncify` rewrote (`deploy/web/build.sh`) so that every function
//!   on a path to `suspend` can save its locals and return, and later run back to where it
//!   was. `suspend` starts that unwinding into a buffer of the page's
//!   (`wgslam_suspend_stack`), the page's wrapper of the entry point awaits `wake`, then calls
//!   the entry point again to rewind, and `suspend` returns.
//!
//! Either way only the page's entry points that it calls through its wrapper may wait (JSPI
//! throws `SuspendError` elsewhere), and no JavaScript frame may lie between such an entry
//! point and the wait.

use std::future::Future;

/// Runs `fut` to completion and returns its output: native, blocking the thread; in the
/// browser, suspending the WebAssembly stack (see the module docs) until it is ready.
pub fn block_on<F: Future>(fut: F) -> F::Output {
    #[cfg(not(target_arch = "wasm32"))]
    {
        pollster::block_on(fut)
    }
    #[cfg(target_arch = "wasm32")]
    {
        suspending::block_on(fut)
    }
}

/// Waits until the GPU has finished the work submitted so far, and map callbacks of
/// buffers whose maps that work completes have run.
pub fn wait_for_submitted(device: &wgpu::Device, queue: &wgpu::Queue) -> Result<(), String> {
    #[cfg(not(target_arch = "wasm32"))]
    {
        let _ = queue;
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| e.to_string())
    }
    #[cfg(target_arch = "wasm32")]
    {
        // The browser's `poll` returns at once; the queue says when its work is done.
        let _ = device;
        let (done, when_done) = callback();
        queue.on_submitted_work_done(move || done(()));
        block_on(when_done);
        Ok(())
    }
}

/// A one-shot callback and the future of its value: the callback form of a wgpu call
/// (`map_async`, `on_submitted_work_done`) as something [`block_on`] can wait for.
pub fn callback<T: Send + 'static>() -> (impl FnOnce(T) + Send + 'static, impl Future<Output = T>) {
    use std::sync::{Arc, Mutex};
    use std::task::{Poll, Waker};
    type Slot<T> = Arc<Mutex<(Option<T>, Option<Waker>)>>;
    let slot: Slot<T> = Arc::new(Mutex::new((None, None)));
    let set = Arc::clone(&slot);
    let call = move |value: T| {
        let mut s = set.lock().unwrap_or_else(|p| p.into_inner());
        s.0 = Some(value);
        if let Some(w) = s.1.take() {
            w.wake();
        }
    };
    let fut = std::future::poll_fn(move |cx| {
        let mut s = slot.lock().unwrap_or_else(|p| p.into_inner());
        match s.0.take() {
            Some(v) => Poll::Ready(v),
            None => {
                s.1 = Some(cx.waker().clone());
                Poll::Pending
            }
        }
    });
    (call, fut)
}

#[cfg(target_arch = "wasm32")]
mod suspending {
    use std::future::Future;
    use std::sync::atomic::{AtomicBool, Ordering};
    use std::sync::Arc;
    use std::task::{Context, Poll, Wake, Waker};

    #[link(wasm_import_module = "wgslam_suspend")]
    extern "C" {
        /// Suspends this WebAssembly stack until [`wake`] is called (the event loop runs
        /// meanwhile; see the module docs for the page's two ways).
        fn suspend();
        /// Resumes the stack [`suspend`] suspended, if any (else nothing).
        fn wake();
    }

    /// The waker of [`block_on`]'s future: records the wake-up (it may come while the
    /// future is being polled, before any suspension) and resumes a suspended stack.
    struct Flag(AtomicBool);

    impl Wake for Flag {
        fn wake(self: Arc<Self>) {
            self.wake_by_ref();
        }
        fn wake_by_ref(self: &Arc<Self>) {
            self.0.store(true, Ordering::SeqCst);
            // SAFETY: a plain JavaScript import without arguments.
            unsafe { wake() }
        }
    }

    pub fn block_on<F: Future>(fut: F) -> F::Output {
        let mut fut = std::pin::pin!(fut);
        let flag = Arc::new(Flag(AtomicBool::new(false)));
        let waker = Waker::from(Arc::clone(&flag));
        let mut cx = Context::from_waker(&waker);
        loop {
            flag.0.store(false, Ordering::SeqCst);
            if let Poll::Ready(v) = fut.as_mut().poll(&mut cx) {
                return v;
            }
            if !flag.0.load(Ordering::SeqCst) {
                // SAFETY: the page's suspending import without arguments; see the module docs.
                unsafe { suspend() }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_callback_called_before_or_after_the_wait_gives_its_value() {
        let (call, value) = callback();
        call(7);
        assert_eq!(block_on(value), 7);
        let (call, value) = callback();
        let caller = std::thread::spawn(move || {
            std::thread::sleep(std::time::Duration::from_millis(20));
            call("later");
        });
        assert_eq!(block_on(value), "later");
        caller.join().unwrap();
    }
}
