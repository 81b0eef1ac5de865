// Image headers and depth PNGs. The first byte picks the reader.
#![no_main]
use libfuzzer_sys::fuzz_target;
use wgslam::dataset::frame;

#[path = "common.rs"]
mod common;

const READERS: &[common::FileReader] = &[
    ("i.png", |p| drop(frame::image_size(p))),
    ("d.png", |p| drop(frame::load_depth(p))),
];

fuzz_target!(|data: &[u8]| common::read_picked(data, READERS));
