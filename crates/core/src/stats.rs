//! Small summary statistics shared by the evaluation, the run report and the benchmarks,
//! so that every "median" in wgslam's outputs means the same thing.

/// The median of `values` as numpy computes it: the middle value for an odd count, the
/// mean of the two middle values for an even count; 0 for an empty list (reports print a
/// number rather than fail). NaNs sort last (`f64::total_cmp`).
pub fn median(values: &[f64]) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    let mut v = values.to_vec();
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

#[cfg(test)]
mod tests {
    use super::median;

    #[test]
    fn median_odd_even_empty() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 3.0, 2.0]), 2.5);
        assert_eq!(median(&[]), 0.0);
    }
}
