//! Seeded noise: a hash for grain, smooth value noise, and segmenter-like jitter of mask
//! boundaries.

use agentstar_render::BitMask;

/// A deterministic hash of a pixel and a seed, in [0, 1).
pub fn hash01(x: u32, y: u32, seed: u32) -> f64 {
    let mut h = x.wrapping_mul(374_761_393)
        ^ y.wrapping_mul(668_265_263)
        ^ seed.wrapping_mul(2_246_822_519);
    h = (h ^ (h >> 13)).wrapping_mul(1_274_126_177);
    ((h ^ (h >> 16)) & 0xffff) as f64 / 65536.0
}

/// Smooth value noise in [−1, 1] with cells of `cell` pixels.
fn value_noise(x: f64, y: f64, cell: f64, seed: u32) -> f64 {
    let (gx, gy) = (x / cell, y / cell);
    let (ix, iy) = (gx.floor(), gy.floor());
    let (fx, fy) = (gx - ix, gy - iy);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let v = |dx: f64, dy: f64| {
        2.0 * hash01((ix + dx + 4096.0) as u32, (iy + dy + 4096.0) as u32, seed) - 1.0
    };
    let (sx, sy) = (s(fx), s(fy));
    let top = v(0.0, 0.0) * (1.0 - sx) + v(1.0, 0.0) * sx;
    let bottom = v(0.0, 1.0) * (1.0 - sx) + v(1.0, 1.0) * sx;
    top * (1.0 - sy) + bottom * sy
}

/// Moves the mask boundary in and out by up to `amplitude_px`, smoothly along the contour,
/// as a segmenter's errors do: a pixel is kept iff its signed distance to the boundary
/// (positive inside) plus `amplitude · noise` is positive. Pixels farther than the amplitude
/// from the boundary never change.
pub fn jitter_boundary(mask: &BitMask, amplitude_px: f64, seed: u64) -> BitMask {
    let (w, h) = (mask.width(), mask.height());
    let r = amplitude_px.ceil() as i64 + 1;
    let seed32 = (seed ^ (seed >> 32)) as u32;
    BitMask::from_fn(w, h, |x, y| {
        let inside = mask.get(x, y);
        // Distance to the nearest pixel of the other label, within the window.
        let mut best = f64::INFINITY;
        for dy in -r..=r {
            for dx in -r..=r {
                let (nx, ny) = (x as i64 + dx, y as i64 + dy);
                let other = if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    inside // outside the image is background
                } else {
                    mask.get(nx as u32, ny as u32) != inside
                };
                if other {
                    best = best.min(((dx * dx + dy * dy) as f64).sqrt());
                }
            }
        }
        if !best.is_finite() {
            return inside;
        }
        // The boundary lies half a pixel from a pixel centre next to the other label.
        let d = best - 0.5;
        let signed = if inside { d } else { -d };
        signed + amplitude_px * value_noise(x as f64, y as f64, 7.0, seed32) > 0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn disc(w: u32, h: u32, r: f64) -> BitMask {
        BitMask::from_fn(w, h, |x, y| {
            let (dx, dy) = (
                x as f64 + 0.5 - w as f64 / 2.0,
                y as f64 + 0.5 - h as f64 / 2.0,
            );
            dx * dx + dy * dy <= r * r
        })
    }

    #[test]
    fn jitter_changes_only_a_band_around_the_boundary_and_is_seeded() {
        let m = disc(96, 96, 30.0);
        let a = jitter_boundary(&m, 2.0, 9);
        let b = jitter_boundary(&m, 2.0, 9);
        assert_eq!(a, b, "same seed, same mask");
        assert_ne!(
            a,
            jitter_boundary(&m, 2.0, 10),
            "another seed moves the boundary"
        );
        let mut changed = 0;
        for y in 0..96 {
            for x in 0..96 {
                if a.get(x, y) != m.get(x, y) {
                    changed += 1;
                    let d =
                        ((x as f64 + 0.5 - 48.0).powi(2) + (y as f64 + 0.5 - 48.0).powi(2)).sqrt();
                    assert!((d - 30.0).abs() <= 3.5, "pixel {x},{y} at radius {d}");
                }
            }
        }
        assert!(changed > 20, "the boundary moved ({changed} pixels)");
        // Interior and exterior far from the boundary are untouched.
        assert!(a.get(48, 48) && !a.get(2, 2));
    }
}
