//! Line-oriented text files (TUM lists and trajectories, ICL-NUIM associations): the one
//! rule for which lines carry data.

/// The data lines of `text` as `(1-based line number, trimmed content)`: a `#` starts a
/// comment (whole-line or trailing), and lines that are blank after removing it are
/// skipped. Line numbers count every line, so errors can name `file:line`.
pub fn data_lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    text.lines().enumerate().filter_map(|(i, raw)| {
        let line = raw.split('#').next().unwrap_or("").trim();
        (!line.is_empty()).then_some((i + 1, line))
    })
}

/// `field` as a finite number (`None` for anything else, `inf` and `NaN` included): a
/// stamp or index column of a list file.
pub fn finite_f64(field: &str) -> Option<f64> {
    field.parse().ok().filter(|s: &f64| s.is_finite())
}

#[cfg(test)]
mod tests {
    use super::data_lines;

    #[test]
    fn comments_and_blanks_are_skipped_numbers_kept() {
        let text = "# header\n\n1 a.png\n  2 b.png  # trailing\n   \n3 c.png";
        let lines: Vec<_> = data_lines(text).collect();
        assert_eq!(lines, vec![(3, "1 a.png"), (4, "2 b.png"), (6, "3 c.png")]);
    }
}
