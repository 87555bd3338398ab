//! Colours a script names: `#rrggbb`, the named colours, and the default palette of
//! parts that set none.

use crate::diagnostics::did_you_mean;

const NAMED_COLORS: &[(&str, [f32; 3])] = &[
    ("black", [0.05, 0.05, 0.05]),
    ("blue", [0.15, 0.3, 0.85]),
    ("brown", [0.45, 0.28, 0.15]),
    ("cyan", [0.1, 0.75, 0.8]),
    ("gray", [0.5, 0.5, 0.5]),
    ("green", [0.2, 0.65, 0.25]),
    ("grey", [0.5, 0.5, 0.5]),
    ("orange", [0.95, 0.55, 0.1]),
    ("pink", [0.95, 0.55, 0.7]),
    ("purple", [0.55, 0.25, 0.7]),
    ("red", [0.85, 0.15, 0.12]),
    ("silver", [0.75, 0.75, 0.78]),
    ("white", [0.95, 0.95, 0.95]),
    ("yellow", [0.95, 0.85, 0.15]),
];

/// Distinct default colours for parts that set none.
pub(crate) const PALETTE: [[f32; 3]; 8] = [
    [0.85, 0.33, 0.25],
    [0.25, 0.55, 0.85],
    [0.35, 0.75, 0.35],
    [0.9, 0.7, 0.2],
    [0.6, 0.4, 0.8],
    [0.2, 0.75, 0.75],
    [0.9, 0.5, 0.7],
    [0.6, 0.6, 0.6],
];

/// A colour written as `#rrggbb` or a name, as 0–1 display values.
pub(crate) fn parse_color(s: &str) -> Result<[f32; 3], String> {
    let t = s.trim();
    if let Some(hex) = t.strip_prefix('#') {
        if hex.len() == 6 {
            if let Ok(v) = u32::from_str_radix(hex, 16) {
                return Ok([
                    ((v >> 16) & 255) as f32 / 255.0,
                    ((v >> 8) & 255) as f32 / 255.0,
                    (v & 255) as f32 / 255.0,
                ]);
            }
        }
        return Err(format!("`color`: `{s}` is not a #rrggbb colour"));
    }
    let lower = t.to_ascii_lowercase();
    if let Some((_, c)) = NAMED_COLORS.iter().find(|(n, _)| *n == lower) {
        return Ok(*c);
    }
    let names: Vec<&str> = NAMED_COLORS.iter().map(|(n, _)| *n).collect();
    Err(format!(
        "`color`: unknown colour name `{s}`{}; use #rrggbb, r, g, b in 0–1, or one of {}",
        did_you_mean(&lower, &names),
        names.join(", ")
    ))
}
