//! Who opens a sequence ([`Interface`]): the command line, the Python package or the
//! browser page, so that an error's remedy names the control that interface has.

/// The interface a sequence is opened through, so that an error names the control that
/// fixes it: a flag, a Python keyword, or what the page can do.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub enum Interface {
    /// `wgslam run`, `eval`, a batch job (flags and `--params` files).
    #[default]
    CommandLine,
    /// The Python package (`params={...}`).
    Python,
    /// The browser page (a picked folder and its camera box).
    Page,
}

impl Interface {
    /// How to give a sequence without intrinsics its camera; `presets`: whether the
    /// camera presets (`fr1`, `fr2`, `fr3`, TUM RGB-D's Freiburg cameras) apply.
    pub fn intrinsics_remedy(self, presets: bool) -> String {
        match (self, presets) {
            (Interface::CommandLine, true) => "pass --camera fr1, fr2 or fr3 (the Freiburg \
                camera in the sequence's name: freiburg1_desk is fr1), or --intrinsics \
                fx,fy,cx,cy, or add a camera.json to the folder"
                .into(),
            (Interface::CommandLine, false) => {
                "pass --intrinsics fx,fy,cx,cy, or add a camera.json to the folder".into()
            }
            (Interface::Python, true) => "pass params={\"camera\": \"fr1\"} (or \"fr2\", \
                \"fr3\": the Freiburg camera in the sequence's name), or \
                params={\"intrinsics\": \"fx,fy,cx,cy\"}, or add a camera.json to the folder"
                .into(),
            (Interface::Python, false) => "pass params={\"intrinsics\": \"fx,fy,cx,cy\"}, or \
                add a camera.json to the folder"
                .into(),
            (Interface::Page, true) => "choose the camera on the page (fr1, fr2 or fr3: the \
                Freiburg camera in the sequence's name, freiburg1_desk is fr1; or four numbers \
                fx,fy,cx,cy), or add a camera.json to the folder"
                .into(),
            (Interface::Page, false) => "type the four numbers fx,fy,cx,cy in the page's \
                camera box, or add a camera.json to the folder"
                .into(),
        }
    }
}
