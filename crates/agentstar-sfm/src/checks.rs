//! What is decided before COLMAP runs: the masks it reads (object and hands excluded, with a
//! margin) and whether the camera moves at all.

use agentstar_mask::BitMask;
use image::GrayImage;

/// `mask` grown by `radius` pixels (a square structuring element).
pub fn dilate(mask: &BitMask, radius: u32) -> BitMask {
    let (w, h) = (mask.width(), mask.height());
    if radius == 0 {
        return mask.clone();
    }
    let r = radius as i64;
    // Rows first, then columns: separable for a square element.
    let mut rows = vec![false; (w * h) as usize];
    for y in 0..h {
        // Distance to the last set pixel to the left, and the next to the right.
        let mut last: Option<i64> = None;
        for x in 0..w {
            if mask.get(x, y) {
                last = Some(x as i64);
            }
            if last.is_some_and(|l| x as i64 - l <= r) {
                rows[(y * w + x) as usize] = true;
            }
        }
        let mut next: Option<i64> = None;
        for x in (0..w).rev() {
            if mask.get(x, y) {
                next = Some(x as i64);
            }
            if next.is_some_and(|n| n - x as i64 <= r) {
                rows[(y * w + x) as usize] = true;
            }
        }
    }
    let mut out = BitMask::new(w, h);
    for x in 0..w {
        let mut last: Option<i64> = None;
        for y in 0..h {
            if rows[(y * w + x) as usize] {
                last = Some(y as i64);
            }
            if last.is_some_and(|l| y as i64 - l <= r) {
                out.set(x, y);
            }
        }
        let mut next: Option<i64> = None;
        for y in (0..h).rev() {
            if rows[(y * w + x) as usize] {
                next = Some(y as i64);
            }
            if next.is_some_and(|n| n - y as i64 <= r) {
                out.set(x, y);
            }
        }
    }
    out
}

/// COLMAP's mask image for a frame: black (0) where features are ignored (the excluded
/// region), white elsewhere.
pub fn colmap_mask(excluded: &BitMask) -> GrayImage {
    GrayImage::from_fn(excluded.width(), excluded.height(), |x, y| {
        image::Luma([if excluded.get(x, y) { 0 } else { 255 }])
    })
}

/// A frame reduced for the motion check: grey values normalised to zero mean and unit
/// variance over the usable background, on a grid of `factor`-pixel blocks.
pub struct Thumb {
    w: u32,
    h: u32,
    value: Vec<f64>,
    usable: Vec<bool>,
}

impl Thumb {
    /// `excluded` must be the frame's size.
    pub fn new(rgb: &image::RgbImage, excluded: &BitMask, factor: u32) -> Thumb {
        let f = factor.max(1);
        let (w, h) = (rgb.width() / f, rgb.height() / f);
        let mut value = vec![0.0; (w * h) as usize];
        let mut usable = vec![true; (w * h) as usize];
        for by in 0..h {
            for bx in 0..w {
                let mut sum = 0.0;
                for y in by * f..(by + 1) * f {
                    for x in bx * f..(bx + 1) * f {
                        let p = rgb.get_pixel(x, y).0;
                        sum += 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64;
                        if excluded.get(x, y) {
                            usable[(by * w + bx) as usize] = false;
                        }
                    }
                }
                value[(by * w + bx) as usize] = sum / (f * f) as f64;
            }
        }
        let n = usable.iter().filter(|&&u| u).count().max(1) as f64;
        let mean = value
            .iter()
            .zip(&usable)
            .filter(|(_, &u)| u)
            .map(|(v, _)| v)
            .sum::<f64>()
            / n;
        let var = value
            .iter()
            .zip(&usable)
            .filter(|(_, &u)| u)
            .map(|(v, _)| (v - mean).powi(2))
            .sum::<f64>()
            / n;
        let sd = var.sqrt().max(1e-9);
        for v in &mut value {
            *v = (*v - mean) / sd;
        }
        Thumb {
            w,
            h,
            value,
            usable,
        }
    }

    /// Mean absolute difference to the same image shifted by one block (right and down):
    /// how much the background changes when the view moves by one block.
    pub fn self_shift_difference(&self) -> Option<f64> {
        let (mut sum, mut n) = (0.0, 0usize);
        for y in 0..self.h {
            for x in 0..self.w {
                let i = (y * self.w + x) as usize;
                for j in [
                    (x + 1 < self.w).then(|| i + 1),
                    (y + 1 < self.h).then(|| i + self.w as usize),
                ]
                .into_iter()
                .flatten()
                {
                    if self.usable[i] && self.usable[j] {
                        sum += (self.value[i] - self.value[j]).abs();
                        n += 1;
                    }
                }
            }
        }
        (n > 0).then(|| sum / n as f64)
    }

    /// Mean absolute difference to another frame over the background both see.
    pub fn difference(&self, other: &Thumb) -> Option<f64> {
        if (self.w, self.h) != (other.w, other.h) {
            return None;
        }
        let (mut sum, mut n) = (0.0, 0usize);
        for i in 0..self.value.len() {
            if self.usable[i] && other.usable[i] {
                sum += (self.value[i] - other.value[i]).abs();
                n += 1;
            }
        }
        (n > 0).then(|| sum / n as f64)
    }
}

/// The block size that brings an image's longer side to at most 400 pixels.
pub fn thumb_factor(width: u32, height: u32) -> u32 {
    width.max(height).div_ceil(400).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dilation_grows_by_the_radius_in_every_direction() {
        let mut m = BitMask::new(20, 20);
        m.set(10, 10);
        let d = dilate(&m, 3);
        assert_eq!(d.count(), 49);
        assert!(d.get(7, 7) && d.get(13, 13) && !d.get(6, 10) && !d.get(10, 14));
        assert_eq!(dilate(&m, 0).count(), 1);
    }

    #[test]
    fn the_colmap_mask_is_black_where_features_are_ignored() {
        let mut m = BitMask::new(4, 2);
        m.set(1, 0);
        let g = colmap_mask(&m);
        assert_eq!(g.get_pixel(1, 0).0[0], 0);
        assert_eq!(g.get_pixel(0, 0).0[0], 255);
    }

    #[test]
    fn a_shifted_view_differs_and_the_same_view_does_not() {
        let tex = |dx: u32| {
            image::RgbImage::from_fn(64, 48, |x, y| {
                let v = ((((x + dx) / 3) * 7 + (y / 3) * 13) % 11) as u8 * 20;
                image::Rgb([v, v, v])
            })
        };
        let none = BitMask::new(64, 48);
        let a = Thumb::new(&tex(0), &none, 1);
        let same = Thumb::new(&tex(0), &none, 1);
        let moved = Thumb::new(&tex(2), &none, 1);
        let s = a.self_shift_difference().expect("texture");
        assert!(a.difference(&same).expect("overlap") < 1e-12);
        assert!(a.difference(&moved).expect("overlap") > 0.5 * s);
        assert_eq!(thumb_factor(1920, 1080), 5);
        assert_eq!(thumb_factor(320, 240), 1);
    }
}
