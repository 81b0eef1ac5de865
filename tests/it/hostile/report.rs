//! Hostile inputs: `report.html`: every string escaped, no script, nothing from outside the batch folder.

use super::*;

// ---- 2. report.html: no script, nothing from outside the batch folder ----------------

/// A `batch.json` of one job with `id` and `backends` (JSON), and that job's `job.json`
/// (failed, with `error`) if `record`.
fn crafted_batch(out: &Path, id: &str, backends: &str, error: &str, record: bool) {
    let spec = format!(
        r#"{{"id": {id}, "sequence": "/data/<script>alert('seq')</script>", "frames": "1..2",
        "downsample": 4, "profile": "robust", "backends": {backends},
        "overrides": [["icp-dist", "0.1\"><script>alert('o')</script>"]]}}"#,
        id = serde_json::to_string(id).unwrap()
    );
    std::fs::create_dir_all(out).unwrap();
    std::fs::write(
        out.join("batch.json"),
        format!(r#"{{"manifest": "m.toml", "jobs": [{spec}]}}"#),
    )
    .unwrap();
    if record {
        let job = out.join("jobs").join(id);
        std::fs::create_dir_all(&job).unwrap();
        std::fs::write(
            job.join("job.json"),
            format!(
                r#"{{"index": 0, "spec": {spec}, "status": "failed", "error": {},
                "runs": {{}}, "gpu_vs_cpu": null, "wall_s": 1.0}}"#,
                serde_json::to_string(error).unwrap()
            ),
        )
        .unwrap();
    }
}

/// Every tag of `html`: its name is one the report uses, it has no event-handler
/// attribute (`on...=`) outside quoted values, and every `src` is a `data:` URI.
fn assert_inert(html: &str) {
    const TAGS: [&str; 21] = [
        "!DOCTYPE",
        "html",
        "head",
        "meta",
        "title",
        "style",
        "body",
        "h1",
        "h2",
        "p",
        "code",
        "table",
        "tr",
        "th",
        "td",
        "a",
        "pre",
        "div",
        "figure",
        "img",
        "figcaption",
    ];
    let mut rest = html;
    while let Some(start) = rest.find('<') {
        let after = &rest[start + 1..];
        let end = after.find('>').expect("an unclosed tag");
        let tag = &after[..end];
        let name = tag
            .trim_start_matches('/')
            .split_whitespace()
            .next()
            .unwrap_or("");
        assert!(
            TAGS.contains(&name),
            "tag <{tag}> is not one of the report's"
        );
        // Outside quoted values: no handler, no unquoted attribute value.
        let mut outside = String::new();
        let mut quoted = false;
        for c in tag.chars() {
            if c == '"' {
                quoted = !quoted;
            } else if !quoted {
                outside.push(c);
            }
        }
        assert!(!quoted, "<{tag}>: unbalanced quotes");
        let lower = outside.to_ascii_lowercase();
        assert!(
            !lower.split_whitespace().any(|w| w.starts_with("on")),
            "<{tag}> has an event handler"
        );
        for (k, _) in tag.match_indices("src=\"") {
            assert!(
                tag[k + 5..].starts_with("data:"),
                "<{tag}>: src not embedded"
            );
        }
        rest = &after[end + 1..];
    }
    assert!(!html.contains("<script"), "a script tag");
}

fn report_escapes_every_string_and_runs_no_script() {
    let dir = common::temp_dir("hostile-report");
    let out = dir.join("out");
    let id = "<img src=x onerror=alert(1)>\"'&";
    crafted_batch(
        &out,
        id,
        r#"["cpu"]"#,
        "</pre><script>alert('error')</script>",
        true,
    );
    ok(wgslam(&["batch", "collect", s(&out)]));
    let html = std::fs::read_to_string(out.join("report.html")).unwrap();
    assert_inert(&html);
    assert!(
        html.contains("&lt;script&gt;alert(&#39;error&#39;)"),
        "{html}"
    );
    assert!(html.contains("&lt;img src=x onerror=alert(1)&gt;&quot;&#39;&amp;"));
}

fn crafted_batch_json_is_refused_not_reported() {
    let dir = common::temp_dir("hostile-batch-json");
    // A picture outside the batch folder that `jobs/../../secret/cpu/` would reach.
    let secret = dir.join("secret/cpu");
    std::fs::create_dir_all(&secret).unwrap();
    image_png(&secret.join("trajectory.png"));
    let cases: [(&str, &str, &str); 4] = [
        ("../../secret", r#"["cpu"]"#, "folder name"),
        ("job", r#"["\" onload=\"alert(1)"]"#, "backends"),
        ("job", r#"["cpu", "cpu"]"#, "backends"),
        ("a\u{0}b", r#"["cpu"]"#, "control character"),
    ];
    for (k, (id, backends, why)) in cases.iter().enumerate() {
        let out = dir.join(format!("out{k}"));
        crafted_batch(&out, id, backends, "x", false);
        let o = wgslam(&["batch", "collect", s(&out)]);
        assert!(!o.status.success(), "{id} {backends}: {}", text(&o));
        assert!(
            text(&o).contains(why) && text(&o).contains("batch.json"),
            "{id} {backends}: {}",
            text(&o)
        );
        assert!(!out.join("report.html").exists());
    }
}

/// A small PNG at `path`.
fn image_png(path: &Path) {
    image::RgbImage::from_pixel(8, 8, image::Rgb([200, 0, 0]))
        .save(path)
        .unwrap();
}

fn a_gt_override_never_quotes_the_file() {
    let dir = common::temp_dir("hostile-gt");
    let secret = dir.join("secret.txt");
    std::fs::write(&secret, "password=hunter2 1 2\nmore secrets\n").unwrap();
    let out = dir.join("out");
    let o = wgslam(&[
        "run",
        s(&common::bundled_icl()),
        "--frames",
        "1..2",
        "--downsample",
        "4",
        "--backend",
        "cpu",
        "--gt",
        s(&secret),
        "--out",
        s(&out),
    ]);
    assert!(!o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("secret.txt:1"), "{}", text(&o));
    assert!(!text(&o).contains("hunter2"), "{}", text(&o));
}

pub fn tests() -> Vec<common::harness::Test> {
    vec![
        plain(
            "report_escapes_every_string_and_runs_no_script",
            report_escapes_every_string_and_runs_no_script,
        ),
        plain(
            "crafted_batch_json_is_refused_not_reported",
            crafted_batch_json_is_refused_not_reported,
        ),
        plain(
            "a_gt_override_never_quotes_the_file",
            a_gt_override_never_quotes_the_file,
        ),
    ]
}
