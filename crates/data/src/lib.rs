//! wgslam's second floor: sequences in, files out.
//!
//! | module | what |
//! |---|---|
//! | [`dataset`] | the layouts a sequence folder may have, their detection, the checks before the first frame, decoding of depth and colour |
//! | [`io`] | bounded reads of user files, TUM trajectories, PLY, text lines, atomic writes |
//! | [`eval`] | ATE (Horn alignment) and RPE, with the TUM benchmark's definitions |
//!
//! Stands on `wgslam-core` (geometry, the host surfel map, the error kinds), whose modules
//! are used here by their own names. Not here: wgpu, the frame loop, the tools; they are
//! the `wgslam` package's, above this crate, and a path from here to them does not compile.

// The browser build reads no files itself (its sequence comes from the page's picker) and
// uses only part of this crate.
#![cfg_attr(target_arch = "wasm32", allow(dead_code))]

pub mod dataset;
pub mod eval;
pub mod io;

use wgslam_core::{geometry, layout, stats};
use wgslam_core::{Error, Result};
