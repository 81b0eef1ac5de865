//! File output and interchange formats: atomic writes, TUM trajectories, PLY point clouds.
//!
//! This module only reads and writes files; it holds no algorithm code. Every output file
//! goes through [`atomic::write_atomic`], so a failed run never leaves a half-written file.

pub mod atomic;
pub mod input;
pub mod outputs;
pub mod ply;
pub(crate) mod text;
pub mod trajectory;

pub use atomic::write_atomic;
pub use ply::{read_ply, write_surfel_map, PlyCloud};
pub use trajectory::{read_tum, write_tum};
