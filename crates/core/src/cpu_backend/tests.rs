//! The CPU backend's own steps: compaction order and the map it keeps.

use super::*;

/// The removal rule on a hand-made map: only unstable surfels (weight below 3) last seen
/// more than 5 frames before frame 10 go; the survivors keep their order and contents.
#[test]
fn compact_removes_old_unstable_surfels_in_order() {
    // (weight, last_frame, removed?)
    let surfels = [
        (1.0, 1, true),   // seen once, 9 frames ago
        (5.0, 1, false),  // stable, however old
        (1.0, 10, false), // seen in this very frame
        (2.9, 5, false),  // unstable but exactly 5 frames old: not more than the limit
        (2.9, 4, true),   // 6 frames old
        (3.0, 0, false),  // weight exactly the stable weight
        (1.0, 2, true),
        (2.0, 9, false),
    ];
    let mut map = SurfelMap::default();
    for (i, &(w, f, _)) in surfels.iter().enumerate() {
        let x = i as f32;
        map.push([x, 1.0, 2.0], [0.0, 0.0, 1.0], [x, 0.0, 0.0], w, f);
    }
    let mut b = CpuBackend::with_map(map.clone());
    let params = CompactParams {
        surfel_count: 0, // filled in by the backend
        frame_id: 10,
        stable_weight: 3.0,
        max_age_frames: 5,
    };
    let kept = b.compact(&params).unwrap();
    let expected: Vec<usize> = (0..surfels.len()).filter(|&i| !surfels[i].2).collect();
    assert_eq!(kept, expected.len());
    let m = b.map();
    assert_eq!(m.len(), expected.len());
    for (slot, &i) in expected.iter().enumerate() {
        assert_eq!(
            m.position_weight[slot], map.position_weight[i],
            "slot {slot}"
        );
        assert_eq!(m.normal_frame[slot], map.normal_frame[i], "slot {slot}");
        assert_eq!(m.color[slot], map.color[i], "slot {slot}");
    }
    // A rule that keeps everything leaves the map as it is; an empty map stays empty.
    let mut b = CpuBackend::with_map(map.clone());
    let keep_all = CompactParams {
        stable_weight: 0.0,
        ..params
    };
    assert_eq!(b.compact(&keep_all).unwrap(), map.len());
    assert_eq!(b.map(), &map);
    assert_eq!(CpuBackend::new().compact(&params).unwrap(), 0);
}
