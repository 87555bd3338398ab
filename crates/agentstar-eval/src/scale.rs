//! Monocular scale alignment: one factor per sequence,
//! `ŝ = exp(median over pixels and frames of (log D_gt − log D_pred))`, over pixels where
//! both depths are valid (finite and positive).

/// The alignment factor from pooled (ground truth, predicted) depth pairs; `None` when no
/// pair is valid.
pub fn median_log_depth_scale(pairs: impl IntoIterator<Item = (f64, f64)>) -> Option<f64> {
    let mut logs: Vec<f64> = pairs
        .into_iter()
        .filter(|(g, p)| g.is_finite() && p.is_finite() && *g > 0.0 && *p > 0.0)
        .map(|(g, p)| g.ln() - p.ln())
        .collect();
    if logs.is_empty() {
        return None;
    }
    logs.sort_by(f64::total_cmp);
    let n = logs.len();
    let median = if n % 2 == 1 {
        logs[n / 2]
    } else {
        0.5 * (logs[n / 2 - 1] + logs[n / 2])
    };
    Some(median.exp())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn recovers_a_known_factor_and_ignores_outliers_and_invalid_pixels() {
        let mut pairs: Vec<(f64, f64)> = (1..100)
            .map(|i| (2.5 * i as f64 * 0.01, i as f64 * 0.01))
            .collect();
        pairs.push((1000.0, 0.001));
        pairs.push((f64::NAN, 1.0));
        pairs.push((1.0, 0.0));
        let s = median_log_depth_scale(pairs).expect("scale");
        assert!((s - 2.5).abs() < 1e-9, "{s}");
        assert_eq!(median_log_depth_scale(vec![(f64::INFINITY, 1.0)]), None);
    }
}
