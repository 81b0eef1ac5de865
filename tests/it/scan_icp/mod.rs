//! Scan registration tests: closed-form alignment, ICP on synthetic data with a known
//! transform, readers on good and malformed input, and real data against references
//! (bundled `assets/`; the full data set in `../shared/data` only for extra checks), and
//! scan odometry and the commands: `synthetic`, `readers`, `real_data`, `odometry_cli`;
//! this module holds the helpers they share.

mod odometry_cli;
mod readers;
mod real_data;
mod synthetic;

use crate::common;

use std::path::{Path, PathBuf};

use glam::{DMat3, DMat4, DQuat, DVec3};
use wgslam::geometry::se3;
use wgslam::scan::*;

fn write(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// Rotation (degrees) and translation (metres) of `inv(reference) * estimate`.
fn pose_err(estimate: &DMat4, reference: &DMat4) -> (f64, f64) {
    let e = se3::inverse_rigid(reference) * *estimate;
    (
        se3::rotation_angle(&e).to_degrees(),
        se3::translation_norm(&e),
    )
}

/// An asymmetric bumpy height field on [-1, 1]^2 sampled every 2 cm (101 x 101 points):
/// curved in both directions so all six degrees of freedom are observable. (A smoother
/// field, `0.3 sin(2x) cos(3y)`, traps point-to-point ICP 0.9 degrees off: with identical
/// grids each point snaps to a neighbour's grid point and the pairing stops changing.)
fn surface() -> Vec<[f32; 3]> {
    let mut v = Vec::new();
    for i in 0..=100 {
        for j in 0..=100 {
            let x = -1.0 + 0.02 * i as f64;
            let y = -1.0 + 0.02 * j as f64;
            let z = 0.2 * (5.0 * x).sin() * (4.0 * y).cos() + 0.1 * x * x + 0.05 * y;
            v.push([x as f32, y as f32, z as f32]);
        }
    }
    v
}

/// A known rigid motion: 4 degrees about (1, 2, 3), translation (5, -3, 2) cm.
fn known_motion() -> DMat4 {
    let r = DMat3::from_quat(DQuat::from_axis_angle(
        DVec3::new(1.0, 2.0, 3.0).normalize(),
        4f64.to_radians(),
    ));
    se3::from_rt(r, DVec3::new(0.05, -0.03, 0.02))
}

fn to_f64(p: &[[f32; 3]]) -> Vec<[f64; 3]> {
    p.iter()
        .map(|q| [q[0] as f64, q[1] as f64, q[2] as f64])
        .collect()
}

pub fn tests() -> Vec<common::harness::Test> {
    [
        synthetic::tests(),
        readers::tests(),
        real_data::tests(),
        odometry_cli::tests(),
    ]
    .into_iter()
    .flatten()
    .collect()
}
