//! Readable labels on images: an 8×8 bitmap font drawn at an integer scale, on an optional
//! background box, so that a person or a model can read frame names, scores and legends.

use image::{Rgb, RgbImage};

/// Width in pixels of `text` drawn at `scale`.
pub fn text_width(text: &str, scale: u32) -> u32 {
    text.chars().count() as u32 * 8 * scale
}

/// Glyphs our labels use that the 8×8 fonts lack (rows top down, bit k = column k from the
/// left): the arrows of candidate labels (`rz:-128 → rx:-20`), comparisons (the `≈` of a
/// refined candidate's nearest named turn, which play-test 13 read as `?`) and dashes.
const EXTRA_GLYPHS: [(char, [u8; 8]); 7] = [
    ('≈', [0x00, 0x4C, 0x32, 0x00, 0x4C, 0x32, 0x00, 0x00]),
    ('→', [0x00, 0x10, 0x20, 0x7F, 0x20, 0x10, 0x00, 0x00]),
    ('←', [0x00, 0x08, 0x04, 0xFE, 0x04, 0x08, 0x00, 0x00]),
    ('≥', [0x02, 0x0C, 0x30, 0x0C, 0x02, 0x00, 0x3E, 0x00]),
    ('≤', [0x20, 0x18, 0x06, 0x18, 0x20, 0x00, 0x3E, 0x00]),
    ('–', [0x00, 0x00, 0x00, 0x3C, 0x00, 0x00, 0x00, 0x00]),
    ('—', [0x00, 0x00, 0x00, 0xFF, 0x00, 0x00, 0x00, 0x00]),
];

/// The glyph of `ch`: ASCII, then Latin-1 (°, ×, ·), then [`EXTRA_GLYPHS`], else '?'.
fn glyph(ch: char) -> [u8; 8] {
    use font8x8::UnicodeFonts;
    font8x8::BASIC_FONTS
        .get(ch)
        .or_else(|| font8x8::LATIN_FONTS.get(ch))
        .or_else(|| EXTRA_GLYPHS.iter().find(|g| g.0 == ch).map(|g| g.1))
        .or_else(|| font8x8::BASIC_FONTS.get('?'))
        .unwrap_or([0; 8])
}

/// Draws `text` with its top-left corner at (x, y); characters outside the font become '?'.
pub fn draw_text(img: &mut RgbImage, x: i64, y: i64, text: &str, scale: u32, color: Rgb<u8>) {
    let scale = scale.max(1) as i64;
    for (ci, ch) in text.chars().enumerate() {
        let glyph = glyph(ch);
        for (row, bits) in glyph.iter().enumerate() {
            for col in 0..8 {
                if bits >> col & 1 == 0 {
                    continue;
                }
                for dy in 0..scale {
                    for dx in 0..scale {
                        let px = x + (ci as i64 * 8 + col) * scale + dx;
                        let py = y + row as i64 * scale + dy;
                        if px >= 0
                            && py >= 0
                            && (px as u32) < img.width()
                            && (py as u32) < img.height()
                        {
                            img.put_pixel(px as u32, py as u32, color);
                        }
                    }
                }
            }
        }
    }
}

/// Fills a rectangle, clipped to the image.
pub fn fill_rect(img: &mut RgbImage, x: i64, y: i64, w: u32, h: u32, color: Rgb<u8>) {
    let x0 = x.max(0) as u32;
    let y0 = y.max(0) as u32;
    let x1 = ((x + w as i64).max(0) as u32).min(img.width());
    let y1 = ((y + h as i64).max(0) as u32).min(img.height());
    for yy in y0..y1 {
        for xx in x0..x1 {
            img.put_pixel(xx, yy, color);
        }
    }
}

/// A text scale that keeps labels legible on an image of the given width.
pub fn scale_for_width(width: u32) -> u32 {
    (width / 320).clamp(1, 4)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drawn(text: &str) -> RgbImage {
        let mut img = RgbImage::new(8 * text.chars().count() as u32, 8);
        draw_text(&mut img, 0, 0, text, 1, Rgb([255, 255, 255]));
        img
    }

    /// A play-test read `rz:-128.25; rx:-20 ? rx:-..` on a candidate sheet: the arrow was
    /// drawn as '?'. Arrows, the degree sign and comparisons now have glyphs of their own.
    #[test]
    fn label_symbols_are_drawn_not_replaced_by_a_question_mark() {
        let unknown = drawn("?");
        for ch in ['→', '←', '°', '×', '≥', '≤', '≈', '–', '—'] {
            let img = drawn(&ch.to_string());
            assert!(img.pixels().any(|p| p.0 != [0, 0, 0]), "{ch} draws nothing");
            assert_ne!(img, unknown, "{ch} is drawn as '?'");
        }
        assert_ne!(drawn("→"), drawn("←"));
        // A character no font has still shows as '?'.
        assert_eq!(drawn("☃"), unknown);
    }
}
