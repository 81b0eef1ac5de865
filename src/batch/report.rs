//! `report.html`: one self-contained page for a batch: a table with one row per job, then
//! per job its trajectory plot and map render for each backend.
//!
//! Self-contained: the pictures are embedded as `data:` URIs and the style is inline, so
//! the file opens from anywhere (a cluster's shared disk, an e-mail attachment) with no
//! network and no files beside it. No scripts, and none can be injected: every string goes
//! through [`esc`] and every attribute value is quoted; the job ids and backends that name
//! picture files were checked by [`super::summary::collect`], so no picture outside the
//! batch folder is read.

use std::fmt::Write as _;
use std::path::Path;

use base64::Engine as _;

use super::summary::{Row, Summary};
use crate::io::atomic::write_atomic;
use crate::tools::run::RunNumbers;
use crate::{Error, Result};

/// The pictures shown per backend, from its run folder, with their captions.
const PICTURES: [(&str, &str); 2] = [
    (
        "trajectory.png",
        "trajectory from above against ground truth, and its error over frames",
    ),
    ("map_color.png", "map render (colour)"),
];

const STYLE: &str = "body{font-family:sans-serif;margin:1.5em;color:#222}\
table{border-collapse:collapse;font-size:13px}th,td{border:1px solid #bbb;padding:3px 6px;\
text-align:right}th{background:#eee}td.l{text-align:left}tr.failed{background:#fdd}\
tr.pending{background:#ffd}.pics{display:flex;flex-wrap:wrap;gap:12px;margin-bottom:10px}\
figure{margin:0}figure img{height:260px;border:1px solid #ccc}figcaption{font-size:12px}\
pre{background:#f6f6f6;padding:6px;white-space:pre-wrap}\
td.health-LOST{background:#f88;font-weight:bold}td.health-recovered{background:#fd8}";

/// Writes `out/report.html` for `s`, reading the pictures from the job folders.
pub fn write(out: &Path, s: &Summary) -> Result<()> {
    let html = render(out, s);
    let path = out.join("report.html");
    write_atomic(&path, |w| {
        w.write_all(html.as_bytes())
            .map_err(|e| Error::write(&path, e))
    })
}

/// The page's HTML.
pub fn render(out: &Path, s: &Summary) -> String {
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>wgslam batch report</title>\
         <style>{STYLE}</style></head><body>\n<h1>wgslam batch: {} jobs</h1>\n\
         <p>{} ok, {} lost, {} failed, {} pending. Folder: <code>{}</code>. ATE: RMSE after rigid \
         alignment; RPE: consecutive frames; GPU vs CPU: each backend tracked on its own, \
         largest camera difference and map points without a match within the radius. \
         Tracking health (no ground truth needed): ok, recovered (frames were lost, not \
         fused, and tracking came back), LOST (the run ended without a tracked pose).</p>\n\
         <p>Tracking health: {}</p>\n",
        s.jobs,
        s.ok,
        s.lost,
        s.failed,
        s.pending,
        esc(&out.display().to_string()),
        health_line(s)
    );
    h.push_str(
        "<table><tr><th>#</th><th>job</th><th>status</th><th>sequence</th><th>frames</th>\
         <th>profile</th><th>backend</th><th>ATE mm</th><th>RPE mm</th><th>RPE deg</th>\
         <th>ms/frame</th><th>peak MiB</th><th>map points</th><th>lost</th>\
         <th>relocalised</th><th>health</th>\
         <th>GPU vs CPU pose mm / deg</th><th>map unmatched</th></tr>\n",
    );
    for r in &s.rows {
        table_rows(&mut h, r);
    }
    h.push_str("</table>\n");
    for r in &s.rows {
        job_section(&mut h, out, r);
    }
    h.push_str("</body></html>\n");
    h
}

/// How many runs are in each tracking-health state, e.g. "3 ok, 1 recovered, 1 LOST".
fn health_line(s: &Summary) -> String {
    let mut counts = std::collections::BTreeMap::<&str, usize>::new();
    for r in &s.rows {
        for n in r.record.iter().flat_map(|rec| rec.runs.values()) {
            if !n.health.is_empty() {
                *counts.entry(n.health.as_str()).or_default() += 1;
            }
        }
    }
    if counts.is_empty() {
        return "-".into();
    }
    ["ok", "degenerate", "recovered", "LOST"]
        .iter()
        .filter_map(|k| counts.get(k).map(|n| format!("{n} {k}")))
        .collect::<Vec<_>>()
        .join(", ")
}

/// One table row per backend of a job (the job's cells spanning them).
fn table_rows(h: &mut String, r: &Row) {
    let rec = r.record.as_ref();
    let backends: Vec<&String> = r.spec.backends.iter().collect();
    let span = backends.len().max(1);
    for (k, b) in backends.iter().enumerate() {
        let _ = write!(h, "<tr class=\"{}\">", esc(&r.status));
        if k == 0 {
            let _ = write!(
                h,
                "<td rowspan=\"{span}\">{}</td><td class=\"l\" rowspan=\"{span}\"><a href=\"#job-{}\">{}</a></td>\
                 <td class=\"l\" rowspan=\"{span}\">{}</td><td class=\"l\" rowspan=\"{span}\">{}</td>\
                 <td rowspan=\"{span}\">{}</td><td class=\"l\" rowspan=\"{span}\">{}</td>",
                r.index,
                esc(&r.id),
                esc(&r.id),
                esc(&r.status),
                esc(&r.spec.sequence.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default()),
                esc(r.spec.frames.as_deref().unwrap_or("all")),
                esc(&r.spec.profile)
            );
        }
        let n: Option<&RunNumbers> = rec.and_then(|rec| rec.runs.get(b.as_str()));
        let f = |x: Option<f64>, digits: usize| {
            x.map(|v| format!("{v:.digits$}"))
                .unwrap_or_else(|| "-".into())
        };
        let _ = write!(
            h,
            "<td class=\"l\">{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td><td>{}</td>",
            esc(b),
            f(n.and_then(|n| n.ate_rmse_mm), 3),
            f(n.and_then(|n| n.rpe_trans_rmse_mm), 3),
            f(n.and_then(|n| n.rpe_rot_rmse_deg), 4),
            f(n.map(|n| n.time_per_frame_median_ms), 1),
            f(n.and_then(|n| n.peak_memory_mib), 0),
            n.map(|n| n.map_points.to_string()).unwrap_or_else(|| "-".into()),
            n.map(|n| n.lost_frames.to_string()).unwrap_or_else(|| "-".into()),
        );
        let health = n.map(|n| n.health.as_str()).unwrap_or("");
        let _ = write!(
            h,
            "<td>{}</td><td class=\"health-{}\">{}</td>",
            n.map(|n| n.relocalised_frames.to_string())
                .unwrap_or_else(|| "-".into()),
            esc(health),
            if health.is_empty() {
                "-".to_string()
            } else {
                esc(health)
            },
        );
        if k == 0 {
            let c = rec.and_then(|rec| rec.gpu_vs_cpu.as_ref());
            let _ = write!(
                h,
                "<td rowspan=\"{span}\">{}</td><td rowspan=\"{span}\">{}</td>",
                c.map(|c| format!("{:.3} / {:.4}", c.pose_max_mm, c.pose_max_deg))
                    .unwrap_or_else(|| "-".into()),
                c.map(|c| format!(
                    "{:.3} % (radius {:.1} mm)",
                    c.map_unmatched_fraction * 100.0,
                    c.map_match_radius_m * 1e3
                ))
                .unwrap_or_else(|| "-".into()),
            );
        }
        h.push_str("</tr>\n");
    }
}

/// A job's heading, error, and pictures.
fn job_section(h: &mut String, out: &Path, r: &Row) {
    let _ = write!(
        h,
        "<h2 id=\"job-{}\">{} {}: {}</h2>\n<p><code>{}</code>, frames {}, downsample {}, profile {}{}</p>\n",
        esc(&r.id),
        r.index,
        esc(&r.id),
        esc(&r.status),
        esc(&r.spec.sequence.display().to_string()),
        esc(r.spec.frames.as_deref().unwrap_or("all")),
        r.spec.downsample,
        esc(&r.spec.profile),
        esc(&r
            .spec
            .overrides
            .iter()
            .map(|(k, v)| format!(", --{k} {v}"))
            .collect::<String>()),
    );
    if let Some(e) = r.record.as_ref().and_then(|rec| rec.error.as_ref()) {
        let _ = writeln!(h, "<pre>{}</pre>", esc(e));
    }
    for b in &r.spec.backends {
        h.push_str("<div class=\"pics\">");
        for (file, caption) in PICTURES {
            let path = out.join("jobs").join(&r.id).join(b).join(file);
            if let Some(bytes) = thumbnail_png(&path) {
                let _ = write!(
                    h,
                    "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\">\
                     <figcaption>{}: {}</figcaption></figure>",
                    esc(&format!("{b} {file}")),
                    base64::engine::general_purpose::STANDARD.encode(bytes),
                    esc(b),
                    esc(caption)
                );
            }
        }
        h.push_str("</div>\n");
    }
}

/// Pictures are shown 260 CSS pixels tall and embedded at 1.5x that, sharp enough on
/// high-DPI screens; full-size renders made a 10-job report 15.7 MB.
const THUMBNAIL_HEIGHT_PX: u32 = 390;

/// The PNG at `path`, scaled down to [`THUMBNAIL_HEIGHT_PX`] if taller; `None` if it is
/// missing or unreadable (the report then leaves it out).
fn thumbnail_png(path: &Path) -> Option<Vec<u8>> {
    let bytes = crate::io::input::read_kind(path, crate::io::input::InputKind::Image).ok()?;
    let img = image::load_from_memory(&bytes).ok()?;
    let img = if img.height() > THUMBNAIL_HEIGHT_PX {
        let w = (img.width() as u64 * THUMBNAIL_HEIGHT_PX as u64 / img.height() as u64) as u32;
        img.resize(
            w.max(1),
            THUMBNAIL_HEIGHT_PX,
            image::imageops::FilterType::Triangle,
        )
    } else {
        img
    };
    let mut bytes = Vec::new();
    let png = image::codecs::png::PngEncoder::new_with_quality(
        &mut bytes,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    );
    img.to_rgb8().write_with_encoder(png).ok()?;
    Some(bytes)
}

/// Escapes text for HTML element content and quoted attribute values (double or single
/// quotes): the page's one escaping function. Every string that reaches the page goes
/// through it, numbers formatted by the page itself excepted; attribute values are always
/// quoted. Text from a batch folder is never trusted (a crafted `batch.json` or
/// `job.json` can hold anything).
fn esc(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    for ch in s.chars() {
        match ch {
            '&' => out.push_str("&amp;"),
            '<' => out.push_str("&lt;"),
            '>' => out.push_str("&gt;"),
            '"' => out.push_str("&quot;"),
            '\'' => out.push_str("&#39;"),
            c => out.push(c),
        }
    }
    out
}
