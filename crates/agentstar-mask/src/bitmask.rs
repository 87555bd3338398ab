//! Bit-packed binary masks (one bit per pixel, 64 pixels per word, rows padded to whole
//! words) and the IoU arithmetic on them, done with popcounts.

/// A binary image; bit `x` of row `y` is pixel (x, y).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BitMask {
    width: u32,
    height: u32,
    words_per_row: usize,
    words: Vec<u64>,
}

impl BitMask {
    pub fn new(width: u32, height: u32) -> Self {
        let words_per_row = (width as usize).div_ceil(64);
        BitMask {
            width,
            height,
            words_per_row,
            words: vec![0; words_per_row * height as usize],
        }
    }

    pub fn from_fn(width: u32, height: u32, mut f: impl FnMut(u32, u32) -> bool) -> Self {
        let mut m = BitMask::new(width, height);
        for y in 0..height {
            for x in 0..width {
                if f(x, y) {
                    m.set(x, y);
                }
            }
        }
        m
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }
    pub fn words_per_row(&self) -> usize {
        self.words_per_row
    }
    pub fn words(&self) -> &[u64] {
        &self.words
    }
    pub fn row(&self, y: u32) -> &[u64] {
        let s = y as usize * self.words_per_row;
        &self.words[s..s + self.words_per_row]
    }

    pub fn get(&self, x: u32, y: u32) -> bool {
        let w = self.words[y as usize * self.words_per_row + (x as usize >> 6)];
        (w >> (x & 63)) & 1 == 1
    }

    pub fn set(&mut self, x: u32, y: u32) {
        self.words[y as usize * self.words_per_row + (x as usize >> 6)] |= 1u64 << (x & 63);
    }

    pub fn clear(&mut self) {
        self.words.fill(0);
    }

    /// Clears rows `y0..=y1` only.
    pub fn clear_rows(&mut self, y0: u32, y1: u32) {
        if y0 > y1 || self.height == 0 {
            return;
        }
        let s = y0 as usize * self.words_per_row;
        let e = (y1.min(self.height - 1) as usize + 1) * self.words_per_row;
        self.words[s..e].fill(0);
    }

    /// Sets pixels `x0..=x1` of row `y` (callers clamp to the image).
    #[inline]
    pub fn set_span(&mut self, y: u32, x0: u32, x1: u32) {
        let row = y as usize * self.words_per_row;
        let (w0, w1) = ((x0 >> 6) as usize, (x1 >> 6) as usize);
        let lo = u64::MAX << (x0 & 63);
        let hi = u64::MAX >> (63 - (x1 & 63));
        if w0 == w1 {
            self.words[row + w0] |= lo & hi;
        } else {
            self.words[row + w0] |= lo;
            for w in &mut self.words[row + w0 + 1..row + w1] {
                *w = u64::MAX;
            }
            self.words[row + w1] |= hi;
        }
    }

    pub fn count(&self) -> u64 {
        self.words.iter().map(|w| w.count_ones() as u64).sum()
    }

    pub fn and(&self, other: &BitMask) -> BitMask {
        self.zip(other, |a, b| a & b)
    }
    pub fn or(&self, other: &BitMask) -> BitMask {
        self.zip(other, |a, b| a | b)
    }
    /// Pixels in `self` but not in `other`.
    pub fn and_not(&self, other: &BitMask) -> BitMask {
        self.zip(other, |a, b| a & !b)
    }
    pub fn not(&self) -> BitMask {
        let mut m = self.clone();
        for w in &mut m.words {
            *w = !*w;
        }
        m.mask_padding();
        m
    }

    fn zip(&self, other: &BitMask, f: impl Fn(u64, u64) -> u64) -> BitMask {
        assert_eq!(
            (self.width, self.height),
            (other.width, other.height),
            "mask sizes differ"
        );
        BitMask {
            width: self.width,
            height: self.height,
            words_per_row: self.words_per_row,
            words: self
                .words
                .iter()
                .zip(&other.words)
                .map(|(&a, &b)| f(a, b))
                .collect(),
        }
    }

    fn mask_padding(&mut self) {
        let rem = self.width % 64;
        if rem == 0 {
            return;
        }
        let keep = (1u64 << rem) - 1;
        for y in 0..self.height as usize {
            self.words[y * self.words_per_row + self.words_per_row - 1] &= keep;
        }
    }

    /// Tight bounding box `(x0, y0, x1, y1)` inclusive, or `None` when empty.
    pub fn bbox(&self) -> Option<(u32, u32, u32, u32)> {
        let (mut x0, mut y0, mut x1, mut y1) = (u32::MAX, u32::MAX, 0, 0);
        for y in 0..self.height {
            for (wi, &w) in self.row(y).iter().enumerate() {
                if w != 0 {
                    let lo = wi as u32 * 64 + w.trailing_zeros();
                    let hi = wi as u32 * 64 + 63 - w.leading_zeros();
                    x0 = x0.min(lo);
                    x1 = x1.max(hi);
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                }
            }
        }
        (x0 != u32::MAX).then_some((x0, y0, x1, y1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn spans_set_exactly_the_requested_pixels() {
        for (x0, x1) in [(0, 0), (3, 70), (63, 64), (0, 199), (64, 127), (130, 130)] {
            let mut m = BitMask::new(200, 2);
            m.set_span(1, x0, x1);
            for x in 0..200 {
                assert_eq!(m.get(x, 1), x >= x0 && x <= x1, "span {x0}..{x1} at {x}");
                assert!(!m.get(x, 0));
            }
            assert_eq!(m.count(), (x1 - x0 + 1) as u64);
        }
    }

    #[test]
    fn not_respects_padding_and_bbox() {
        let m = BitMask::from_fn(70, 3, |x, y| x == 5 && y == 2);
        assert_eq!(m.not().count(), 70 * 3 - 1);
        assert_eq!(m.bbox(), Some((5, 2, 5, 2)));
        assert_eq!(BitMask::new(4, 4).bbox(), None);
    }
}
