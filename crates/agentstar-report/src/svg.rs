//! Line charts as inline SVG: one x category per keyframe, gaps where a value is missing.

use crate::html::esc;
use std::fmt::Write;

/// One line of a chart.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    /// A CSS colour.
    pub color: String,
    pub values: Vec<Option<f64>>,
}

const W: f64 = 640.0;
const H: f64 = 220.0;
const LEFT: f64 = 56.0;
const RIGHT: f64 = 28.0;
const TOP: f64 = 28.0;
const BOTTOM: f64 = 40.0;

/// A "nice" step for about `n` ticks over `span`.
fn tick_step(span: f64, n: f64) -> f64 {
    let raw = (span / n).max(1e-12);
    let mag = 10f64.powf(raw.log10().floor());
    let r = raw / mag;
    let nice = if r < 1.5 {
        1.0
    } else if r < 3.5 {
        2.0
    } else if r < 7.5 {
        5.0
    } else {
        10.0
    };
    nice * mag
}

fn fmt_tick(v: f64, step: f64) -> String {
    let decimals = (-step.log10().floor()).clamp(0.0, 6.0) as usize;
    format!("{v:.decimals$}")
}

/// A line chart over `x_labels` (every label drawn when they fit, else every k-th), with an
/// optional horizontal reference line (value and label). Non-finite values are gaps.
pub fn line_chart(
    title: &str,
    y_label: &str,
    x_labels: &[String],
    series: &[Series],
    reference: Option<(f64, &str)>,
) -> String {
    let finite = series
        .iter()
        .flat_map(|s| s.values.iter().flatten().copied())
        .chain(reference.map(|r| r.0))
        .filter(|v| v.is_finite());
    let (mut lo, mut hi) = finite.fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| {
        (a.min(v), b.max(v))
    });
    if !lo.is_finite() {
        (lo, hi) = (0.0, 1.0);
    }
    if hi - lo < 1e-9 {
        lo -= 0.5;
        hi += 0.5;
    }
    let step = tick_step(hi - lo, 4.0);
    let lo = (lo / step).floor() * step;
    let hi = (hi / step).ceil() * step;
    let n = x_labels
        .len()
        .max(series.iter().map(|s| s.values.len()).max().unwrap_or(0))
        .max(1);
    let plot_w = W - LEFT - RIGHT;
    let plot_h = H - TOP - BOTTOM;
    let x = |i: usize| {
        if n == 1 {
            LEFT + plot_w / 2.0
        } else {
            LEFT + plot_w * i as f64 / (n - 1) as f64
        }
    };
    let y = |v: f64| TOP + plot_h * (1.0 - (v - lo) / (hi - lo));
    let mut s = String::new();
    let _ = write!(
        s,
        r#"<svg class="chart" viewBox="0 0 {W} {H}" role="img" aria-label="{t}"><title>{t}</title><text x="{LEFT}" y="16" class="chart-title">{t}</text>"#,
        t = esc(title)
    );
    // Grid and y ticks.
    let mut v = lo;
    while v <= hi + step * 0.5 {
        let _ = write!(
            s,
            r##"<line x1="{LEFT}" x2="{x2}" y1="{yy:.1}" y2="{yy:.1}" stroke="#ddd"/><text x="{tx}" y="{ty:.1}" text-anchor="end" class="tick">{lab}</text>"##,
            x2 = W - RIGHT,
            yy = y(v),
            tx = LEFT - 6.0,
            ty = y(v) + 4.0,
            lab = fmt_tick(v, step)
        );
        v += step;
    }
    let _ = write!(
        s,
        r#"<text transform="translate(12 {cy}) rotate(-90)" text-anchor="middle" class="tick">{yl}</text>"#,
        cy = TOP + plot_h / 2.0,
        yl = esc(y_label)
    );
    // X labels: as many as fit without overlapping.
    let longest = x_labels
        .iter()
        .map(|l| l.chars().count())
        .max()
        .unwrap_or(1) as f64;
    let fit = ((plot_w / (6.5 * longest + 10.0)).floor() as usize).max(1);
    let every = n.div_ceil(fit).max(1);
    for (i, l) in x_labels.iter().enumerate() {
        if i % every == 0 {
            let _ = write!(
                s,
                r#"<text x="{xx:.1}" y="{yy}" text-anchor="middle" class="tick">{l}</text>"#,
                xx = x(i),
                yy = H - BOTTOM + 16.0,
                l = esc(l)
            );
        }
    }
    if let Some((rv, rl)) = reference {
        let _ = write!(
            s,
            r##"<line x1="{LEFT}" x2="{x2}" y1="{yy:.1}" y2="{yy:.1}" stroke="#c33" stroke-dasharray="5 4"/><text x="{x2}" y="{ty:.1}" text-anchor="end" class="tick" fill="#c33">{rl}</text>"##,
            x2 = W - RIGHT,
            yy = y(rv),
            ty = y(rv) - 4.0,
            rl = esc(rl)
        );
    }
    for se in series {
        let mut d = String::new();
        let mut pen_up = true;
        for (i, v) in se.values.iter().enumerate() {
            match v.filter(|v| v.is_finite()) {
                Some(v) => {
                    let _ = write!(
                        d,
                        "{}{:.1} {:.1} ",
                        if pen_up { "M" } else { "L" },
                        x(i),
                        y(v)
                    );
                    pen_up = false;
                }
                None => pen_up = true,
            }
        }
        let _ = write!(
            s,
            r#"<path d="{d}" fill="none" stroke="{c}" stroke-width="2"/>"#,
            c = esc(&se.color)
        );
        for (i, v) in se.values.iter().enumerate() {
            if let Some(v) = v.filter(|v| v.is_finite()) {
                let _ = write!(
                    s,
                    r#"<circle cx="{:.1}" cy="{:.1}" r="3" fill="{c}"><title>{}: {} = {}</title></circle>"#,
                    x(i),
                    y(v),
                    esc(x_labels.get(i).map_or("", |l| l.as_str())),
                    esc(&se.name),
                    fmt_tick(v, step / 100.0),
                    c = esc(&se.color)
                );
            }
        }
    }
    // Legend.
    let mut lx = LEFT;
    for se in series {
        let _ = write!(
            s,
            r#"<rect x="{lx}" y="{ly}" width="10" height="10" fill="{c}"/><text x="{tx}" y="{ty}" class="tick">{n}</text>"#,
            ly = H - 14.0,
            tx = lx + 14.0,
            ty = H - 5.0,
            c = esc(&se.color),
            n = esc(&se.name)
        );
        lx += 24.0 + 7.0 * se.name.chars().count() as f64;
    }
    s.push_str("</svg>");
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_round_numbers() {
        assert_eq!(tick_step(1.0, 4.0), 0.2);
        assert_eq!(tick_step(37.0, 4.0), 10.0);
        assert_eq!(fmt_tick(0.98, 0.01), "0.98");
    }

    #[test]
    fn gaps_break_the_line_and_labels_are_escaped() {
        let svg = line_chart(
            "IoU <visible>",
            "IoU",
            &["a".into(), "b".into(), "c".into()],
            &[Series {
                name: "iou".into(),
                color: "#06c".into(),
                values: vec![Some(0.9), None, Some(f64::NAN)],
            }],
            Some((0.98, "gate")),
        );
        assert!(svg.contains("IoU &lt;visible&gt;"));
        // One point only: a single move, no line segment, one marker.
        assert_eq!(svg.matches("<circle").count(), 1);
        assert!(!svg.contains(" L"));
        assert!(svg.starts_with("<svg") && svg.ends_with("</svg>"));
    }
}
