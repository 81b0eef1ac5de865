//! Pinhole intrinsics, lens distortion and named presets (projection and back-projection
//! are the CPU twins' helpers in `crate::cpu`, shared with the shaders). The kernels see a
//! pinhole camera only: a lens's distortion is removed from the images when they are
//! decoded (`wgslam_data`'s `dataset::undistort`), through [`Distortion`].
//!
//! Pixel coordinates: `u` to the right (column), `v` down (row), pixel centres at integers.
//! Camera coordinates: metres, `z` along the optical axis. `fy` may be negative (ICL-NUIM's
//! official intrinsics use `fy = -480`): projection and back-projection use it as given,
//! so poses stay in the dataset's own convention and no sign flip is needed anywhere.

use serde::{Deserialize, Serialize};

/// The named cameras `--camera` (and the page's camera box) offer, by any of their names.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Preset {
    Icl,
    Fr1,
    Fr2,
    Fr3,
}

impl Preset {
    fn named(name: &str) -> Option<Preset> {
        match name.to_ascii_lowercase().as_str() {
            "icl" | "icl-nuim" | "icl_nuim" => Some(Preset::Icl),
            "fr1" | "freiburg1" | "tum-fr1" => Some(Preset::Fr1),
            "fr2" | "freiburg2" | "tum-fr2" => Some(Preset::Fr2),
            "fr3" | "freiburg3" | "tum-fr3" => Some(Preset::Fr3),
            _ => None,
        }
    }
}

/// Pinhole intrinsics for an image of `width` x `height` pixels.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Intrinsics {
    pub width: u32,
    pub height: u32,
    pub fx: f32,
    pub fy: f32,
    pub cx: f32,
    pub cy: f32,
}

impl Intrinsics {
    /// ICL-NUIM official intrinsics (640x480, negative fy).
    pub const ICL_NUIM: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 481.20,
        fy: -480.0,
        cx: 319.5,
        cy: 239.5,
    };
    /// TUM RGB-D freiburg1 (640x480).
    pub const TUM_FR1: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 517.3,
        fy: 516.5,
        cx: 318.6,
        cy: 255.3,
    };
    /// TUM RGB-D freiburg2 (640x480).
    pub const TUM_FR2: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 520.9,
        fy: 521.0,
        cx: 325.1,
        cy: 249.7,
    };
    /// TUM RGB-D freiburg3 (640x480).
    pub const TUM_FR3: Intrinsics = Intrinsics {
        width: 640,
        height: 480,
        fx: 535.4,
        fy: 539.2,
        cx: 320.1,
        cy: 247.6,
    };

    /// A named preset: `icl`, `fr1`, `fr2`, `fr3` (its lens: [`Distortion::preset`]).
    pub fn preset(name: &str) -> Option<Intrinsics> {
        match Preset::named(name)? {
            Preset::Icl => Some(Self::ICL_NUIM),
            Preset::Fr1 => Some(Self::TUM_FR1),
            Preset::Fr2 => Some(Self::TUM_FR2),
            Preset::Fr3 => Some(Self::TUM_FR3),
        }
    }

    /// These intrinsics with the four numbers `fx,fy,cx,cy` (pixels) of `text` in place of
    /// their own (the command line's `--intrinsics`, the page's camera box); the error says
    /// what the text should be.
    pub fn with_focal_centre(&self, text: &str) -> Result<Intrinsics, &'static str> {
        let v: Vec<f32> = text
            .split(',')
            .map(|x| x.trim().parse::<f32>())
            .collect::<Result<_, _>>()
            .map_err(|_| "want fx,fy,cx,cy")?;
        if v.len() != 4 || v[0] == 0.0 || v[1] == 0.0 || v.iter().any(|x| !x.is_finite()) {
            return Err("want four finite numbers fx,fy,cx,cy with fx, fy non-zero");
        }
        Ok(Intrinsics {
            fx: v[0],
            fy: v[1],
            cx: v[2],
            cy: v[3],
            ..*self
        })
    }

    /// Intrinsics after keeping every `factor`-th pixel in each direction
    /// (pixel `(u', v')` of the result is pixel `(factor u', factor v')` of the original).
    pub fn downsampled(&self, factor: u32) -> Intrinsics {
        let f = factor as f32;
        Intrinsics {
            width: self.width.div_ceil(factor),
            height: self.height.div_ceil(factor),
            fx: self.fx / f,
            fy: self.fy / f,
            cx: self.cx / f,
            cy: self.cy / f,
        }
    }

    /// Number of pixels.
    pub fn pixels(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// `[fx, fy, cx, cy]` in pixels: the first four floats of the kernels' camera block
    /// (`crate::layout::Camera::new`).
    #[inline]
    pub fn floats(&self) -> [f32; 4] {
        [self.fx, self.fy, self.cx, self.cy]
    }

    /// The camera of `[fx, fy, cx, cy]` (pixels, as [`Intrinsics::floats`] gives them) at
    /// `width` x `height` pixels.
    pub fn from_floats([fx, fy, cx, cy]: [f32; 4], (width, height): (u32, u32)) -> Intrinsics {
        Intrinsics {
            width,
            height,
            fx,
            fy,
            cx,
            cy,
        }
    }
}

/// A lens's distortion (the Brown-Conrady model, coefficients in the order OpenCV, ROS's
/// `CameraInfo` (`plumb_bob`) and the TUM RGB-D benchmark give them: `k1, k2, p1, p2, k3`):
/// the ideal pinhole camera's normalised point `(x, y) = ((u - cx) / fx, (v - cy) / fy)`
/// is seen at [`Distortion::distort`]`(x, y)`. Radial `k1, k2, k3`, tangential `p1, p2`,
/// all dimensionless.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Distortion {
    pub k1: f64,
    pub k2: f64,
    pub p1: f64,
    pub p2: f64,
    pub k3: f64,
}

impl Distortion {
    /// TUM RGB-D freiburg1's colour camera (the benchmark's published calibration; its depth
    /// images are registered to that camera's distorted pixels, so both are undistorted).
    pub const TUM_FR1: Distortion = Distortion {
        k1: 0.2624,
        k2: -0.9531,
        p1: -0.0054,
        p2: 0.0026,
        k3: 1.1633,
    };
    /// TUM RGB-D freiburg2's colour camera (as [`Distortion::TUM_FR1`]).
    pub const TUM_FR2: Distortion = Distortion {
        k1: 0.2312,
        k2: -0.7849,
        p1: -0.0033,
        p2: -0.0001,
        k3: 0.9172,
    };

    /// The lens of a named preset (as [`Intrinsics::preset`]): freiburg1 and freiburg2 have
    /// one; freiburg3's images were undistorted by the benchmark already and ICL-NUIM's are
    /// rendered through a pinhole, so `None` for those (and for an unknown name).
    pub fn preset(name: &str) -> Option<Distortion> {
        match Preset::named(name)? {
            Preset::Fr1 => Some(Self::TUM_FR1),
            Preset::Fr2 => Some(Self::TUM_FR2),
            Preset::Icl | Preset::Fr3 => None,
        }
    }

    /// The coefficients `[k1, k2, p1, p2, k3]` (a `camera.json`'s `distortion`, a
    /// `CameraInfo`'s `D`), which must be finite; all zero is no distortion (`None`).
    pub fn from_coefficients(c: [f64; 5]) -> Result<Option<Distortion>, &'static str> {
        if c.iter().any(|v| !v.is_finite()) {
            return Err("distortion coefficients k1, k2, p1, p2, k3 must be finite");
        }
        let [k1, k2, p1, p2, k3] = c;
        Ok((c != [0.0; 5]).then_some(Distortion { k1, k2, p1, p2, k3 }))
    }

    /// `[k1, k2, p1, p2, k3]`.
    pub fn coefficients(&self) -> [f64; 5] {
        [self.k1, self.k2, self.p1, self.p2, self.k3]
    }

    /// Where the lens shows the ideal normalised point `(x, y)`: its distorted normalised
    /// point.
    pub fn distort(&self, x: f64, y: f64) -> (f64, f64) {
        let r2 = x * x + y * y;
        let radial = 1.0 + r2 * (self.k1 + r2 * (self.k2 + r2 * self.k3));
        (
            x * radial + 2.0 * self.p1 * x * y + self.p2 * (r2 + 2.0 * x * x),
            y * radial + self.p1 * (r2 + 2.0 * y * y) + 2.0 * self.p2 * x * y,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_bring_their_lens_by_any_of_their_names() {
        for name in ["fr1", "FREIBURG1", "tum-fr1"] {
            assert_eq!(Intrinsics::preset(name), Some(Intrinsics::TUM_FR1));
            assert_eq!(Distortion::preset(name), Some(Distortion::TUM_FR1));
        }
        assert_eq!(Distortion::preset("fr2"), Some(Distortion::TUM_FR2));
        for pinhole in ["fr3", "icl"] {
            assert!(Intrinsics::preset(pinhole).is_some());
            assert_eq!(Distortion::preset(pinhole), None);
        }
        assert_eq!(Distortion::preset("kinect"), None);
    }

    #[test]
    fn the_lens_moves_points_outward_with_radius_as_freiburg1_barrel() {
        let lens = Distortion::TUM_FR1;
        assert_eq!(lens.distort(0.0, 0.0), (0.0, 0.0));
        // k1 > 0 dominates near the centre: a point moves away from it.
        let (x, y) = lens.distort(0.3, 0.0);
        assert!(x > 0.3 && y.abs() < 0.01, "{x} {y}");
        assert!(Distortion::from_coefficients([f64::NAN, 0.0, 0.0, 0.0, 0.0]).is_err());
        assert_eq!(Distortion::from_coefficients([0.0; 5]), Ok(None));
    }
}
