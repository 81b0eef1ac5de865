//! The files a page was given (a picked or dropped folder, or the bundled frames) as a
//! [`DatasetFiles`] source: the page hands over every file's path and size up front
//! ([`super::add_file`]); a file's bytes are asked of the page only when the dataset code
//! reads it (a frame list once, each image when its frame is decoded), through the page's
//! reader function (`read(path) -> Promise<Uint8Array>`, [`super::set_reader`]), waited for
//! by suspending the WebAssembly stack as GPU waits are ([`crate::gpu::wait`]). So a long
//! sequence is never in memory as a whole: one frame's two images at a time.

use std::cell::RefCell;
use std::path::Path;
use std::rc::Rc;

use wasm_bindgen::prelude::*;

use crate::dataset::source::{Listed, ReadFile};
use crate::{Error, Result};

thread_local! {
    /// The page's reader: `read(path) -> Promise<Uint8Array>`.
    static READER: RefCell<Option<js_sys::Function>> = const { RefCell::new(None) };
}

/// Sets the page's reader function.
pub fn set_reader(reader: js_sys::Function) {
    READER.with_borrow_mut(|r| *r = Some(reader));
}

/// The page's files by path and size; reads go to the page's reader.
pub type PageFiles = Listed<PageReader>;

/// Reads a listed file through the page's reader function ([`set_reader`]).
#[derive(Debug, Default, Clone, Copy, PartialEq)]
pub struct PageReader;

impl ReadFile for PageReader {
    fn read_file(&self, path: &Path) -> Result<Vec<u8>> {
        read_from_page(path)
    }
}

/// Asks the page's reader for `path` and waits (suspending) for the bytes.
fn read_from_page(path: &Path) -> Result<Vec<u8>> {
    let failed = |why: String| {
        Error::io(
            path,
            std::io::Error::other(format!("the browser could not read the file: {why}")),
        )
    };
    let reader = READER
        .with_borrow(|r| r.clone())
        .ok_or_else(|| failed("the page set no reader".into()))?;
    let name = path.to_string_lossy().into_owned();
    let promise = reader
        .call1(&JsValue::NULL, &name.into())
        .map_err(|e| failed(describe(&e)))?;
    let promise: js_sys::Promise = promise
        .dyn_into()
        .map_err(|_| failed("the reader did not return a promise".into()))?;
    let (done, bytes) = crate::gpu::wait::callback::<std::result::Result<Vec<u8>, String>>();
    // Whichever handler runs first takes the one-shot callback.
    let done = Rc::new(RefCell::new(Some(done)));
    let (on_ok, on_err) = (Rc::clone(&done), done);
    let ok = Closure::once(move |v: JsValue| {
        if let Some(d) = on_ok.borrow_mut().take() {
            d(Ok(js_sys::Uint8Array::new(&v).to_vec()));
        }
    });
    let err = Closure::once(move |e: JsValue| {
        if let Some(d) = on_err.borrow_mut().take() {
            d(Err(describe(&e)));
        }
    });
    let _ = promise.then2(&ok, &err);
    // Both closures live until the promise settled (this waits for it).
    crate::gpu::wait::block_on(bytes).map_err(failed)
}

/// A JavaScript error's message, or the value as text.
fn describe(e: &JsValue) -> String {
    e.dyn_ref::<js_sys::Error>()
        .map(|e| String::from(e.message()))
        .or_else(|| e.as_string())
        .unwrap_or_else(|| format!("{e:?}"))
}
