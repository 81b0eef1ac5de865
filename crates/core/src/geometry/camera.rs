//! Pinhole intrinsics and named presets (projection and back-projection are the CPU twins'
//! helpers in `crate::cpu`, shared with the shaders).
//!
//! Pixel coordinates: `u` to the right (column), `v` down (row), pixel centres at integers.
//! Camera coordinates: metres, `z` along the optical axis. `fy` may be negative (ICL-NUIM's
//! official intrinsics use `fy = -480`): projection and back-projection use it as given,
//! so poses stay in the dataset's own convention and no sign flip is needed anywhere.

use serde::{Deserialize, Serialize};

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

    /// A named preset: `icl`, `fr1`, `fr2`, `fr3`.
    pub fn preset(name: &str) -> Option<Intrinsics> {
        match name.to_ascii_lowercase().as_str() {
            "icl" | "icl-nuim" | "icl_nuim" => Some(Self::ICL_NUIM),
            "fr1" | "freiburg1" | "tum-fr1" => Some(Self::TUM_FR1),
            "fr2" | "freiburg2" | "tum-fr2" => Some(Self::TUM_FR2),
            "fr3" | "freiburg3" | "tum-fr3" => Some(Self::TUM_FR3),
            _ => None,
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
