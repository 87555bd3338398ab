//! Images sized for a vision-language model: the limits every image a tool returns keeps
//! (one place, used by every writer), fitting an image into them, and contact sheets that
//! are paged rather than stretched, with labels drawn at a size that stays readable.
//!
//! The limits are those of today's Claude models (a long side of 1568 px and about 1.15
//! megapixels; larger images are shrunk by the client, which makes small labels
//! unreadable); other models accept less or the same. A sheet is composed at its final
//! size: tiles are shrunk (never below [`MIN_TILE_LONG_SIDE_PX`] while paging can help)
//! and the labels are drawn afterwards, so no resize ever touches a label.

use crate::text::{draw_text, fill_rect, text_width};
use image::imageops::FilterType;
use image::{ImageBuffer, Pixel, Rgb, RgbImage};

/// The longest side of any image a tool returns, pixels.
pub const MAX_LONG_SIDE_PX: u32 = 1568;
/// The most pixels of any image a tool returns (about 1.15 megapixels).
pub const MAX_PIXELS: u64 = 1_150_000;
/// Text scale of labels, titles and legends (the 8×8 font drawn 2×: 16 px glyphs).
pub const LABEL_SCALE: u32 = 2;
/// Tiles are not shrunk below this long side to fit one page; the sheet is paged instead.
pub const MIN_TILE_LONG_SIDE_PX: u32 = 240;
/// Lines a tile label may wrap to; the rest is cut with `..`.
pub const MAX_LABEL_LINES: usize = 7;

/// Background of sheets and label bars.
pub const SHEET_BACKGROUND: Rgb<u8> = Rgb([235, 235, 235]);
const LABEL_BAR: Rgb<u8> = Rgb([40, 40, 48]);
const PAD: u32 = 4;

/// Whether a `width`×`height` image keeps the limits.
pub fn within_limits(width: u32, height: u32) -> bool {
    width.max(height) <= MAX_LONG_SIDE_PX && width as u64 * height as u64 <= MAX_PIXELS
}

/// The largest factor (≤ 1) that brings `width`×`height` within the limits.
pub fn limit_factor(width: u32, height: u32) -> f64 {
    let (w, h) = (width.max(1) as f64, height.max(1) as f64);
    let by_side = MAX_LONG_SIDE_PX as f64 / w.max(h);
    let by_area = (MAX_PIXELS as f64 / (w * h)).sqrt();
    by_side.min(by_area).min(1.0)
}

/// `img` shrunk (aspect kept) until it keeps the limits; unchanged when it already does.
pub fn fit_to_limits<P>(img: ImageBuffer<P, Vec<P::Subpixel>>) -> ImageBuffer<P, Vec<P::Subpixel>>
where
    P: Pixel + 'static,
    P::Subpixel: 'static,
{
    if within_limits(img.width(), img.height()) {
        return img;
    }
    let f = limit_factor(img.width(), img.height());
    // Rounding down, then one more pixel where rounding still leaves it over.
    let mut w = ((img.width() as f64 * f).floor() as u32).max(1);
    let mut h = ((img.height() as f64 * f).floor() as u32).max(1);
    while !within_limits(w, h) {
        w = (w - 1).max(1);
        h = (h - 1).max(1);
    }
    image::imageops::resize(&img, w, h, FilterType::Triangle)
}

/// `img` scaled by `factor` (aspect kept, at least 1×1).
pub fn scaled(img: &RgbImage, factor: f64) -> RgbImage {
    if (factor - 1.0).abs() < 1e-9 {
        return img.clone();
    }
    let w = ((img.width() as f64 * factor).round() as u32).max(1);
    let h = ((img.height() as f64 * factor).round() as u32).max(1);
    let filter = if factor > 1.0 {
        FilterType::CatmullRom
    } else {
        FilterType::Triangle
    };
    image::imageops::resize(img, w, h, filter)
}

/// Splits `text` into lines of at most `max_chars` characters, breaking after spaces and
/// `;` where it can, into at most `max_lines` lines (the last cut with `..`).
pub fn wrap_label(text: &str, max_chars: usize, max_lines: usize) -> Vec<String> {
    let max_chars = max_chars.max(3);
    let chars: Vec<char> = text.chars().collect();
    let mut lines = Vec::new();
    let mut start = 0;
    while start < chars.len() {
        // Leading spaces of a continuation line are dropped.
        while start < chars.len() && chars[start] == ' ' && !lines.is_empty() {
            start += 1;
        }
        if start >= chars.len() {
            break;
        }
        let rest = chars.len() - start;
        if lines.len() + 1 == max_lines && rest > max_chars {
            let mut s: String = chars[start..start + max_chars - 2].iter().collect();
            s.push_str("..");
            lines.push(s);
            return lines;
        }
        let end = if rest <= max_chars {
            chars.len()
        } else {
            let window = &chars[start..start + max_chars];
            match window.iter().rposition(|&c| c == ' ' || c == ';') {
                Some(k) if k > 0 => start + k + 1,
                _ => start + max_chars,
            }
        };
        lines.push(
            chars[start..end]
                .iter()
                .collect::<String>()
                .trim_end()
                .to_string(),
        );
        start = end;
    }
    lines
}

/// How a sheet's tiles are laid out on its pages.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SheetLayout {
    pub columns: usize,
    /// The factor every tile is scaled by (≤ 1).
    pub tile_factor: f64,
    /// The box every tile is centred in.
    pub tile_width: u32,
    pub tile_height: u32,
    pub label_lines: usize,
    pub rows_per_page: usize,
    pub pages: usize,
}

fn line_height() -> u32 {
    10 * LABEL_SCALE
}

fn chars_per_line(width: u32) -> usize {
    (width.saturating_sub(4) / (8 * LABEL_SCALE)).max(3) as usize
}

/// The most lines a sheet's title wraps to: enough for a legend named in words over a
/// narrow sheet (a title of two lines cut the compare sheet's legend off).
const MAX_TITLE_LINES: usize = 8;

/// Lines of a title over a sheet `width` wide.
fn title_lines(title: &str, width: u32) -> Vec<String> {
    if title.is_empty() {
        vec![]
    } else {
        wrap_label(
            title,
            chars_per_line(width.saturating_sub(2 * PAD)),
            MAX_TITLE_LINES,
        )
    }
}

/// The layout of `tiles` in `columns`: the largest tiles (never enlarged) that put every
/// tile on one page within the limits, or, when that would take tiles under
/// [`MIN_TILE_LONG_SIDE_PX`], tiles of that size over several pages.
pub fn sheet_layout(tiles: &[(String, RgbImage)], columns: usize, title: &str) -> SheetLayout {
    let n = tiles.len().max(1);
    let columns = columns.clamp(1, n);
    let natural_w = tiles.iter().map(|t| t.1.width()).max().unwrap_or(64).max(1);
    let natural_h = tiles
        .iter()
        .map(|t| t.1.height())
        .max()
        .unwrap_or(64)
        .max(1);
    let natural_long = natural_w.max(natural_h) as f64;
    let mut f = 1.0f64;
    loop {
        let tw = ((natural_w as f64 * f).round() as u32).max(1);
        let th = ((natural_h as f64 * f).round() as u32).max(1);
        let cpl = chars_per_line(tw);
        let label_lines = tiles
            .iter()
            .map(|(l, _)| wrap_label(l, cpl, MAX_LABEL_LINES).len())
            .max()
            .unwrap_or(1)
            .max(1);
        let label_h = label_lines as u32 * line_height() + LABEL_SCALE * 2;
        let width = columns as u32 * (tw + PAD) + PAD;
        // Room for the page number a page of several adds to the title.
        let title_h = title_lines(&format!("{title} (page 00/00)"), width).len() as u32
            * line_height()
            * u32::from(!title.is_empty())
            + if title.is_empty() { 0 } else { 2 * PAD };
        let row_h = th + label_h + PAD;
        let rows_total = n.div_ceil(columns);
        // Rows that fit on a page within both limits.
        let mut rows_fit = 0usize;
        while rows_fit < rows_total {
            let h = title_h + (rows_fit as u32 + 1) * row_h + PAD;
            if within_limits(width, h) {
                rows_fit += 1;
            } else {
                break;
            }
        }
        let long = natural_long * f;
        let at_min = long <= MIN_TILE_LONG_SIDE_PX as f64 + 0.5;
        if (rows_fit >= 1 && (rows_fit >= rows_total || at_min)) || long < 8.0 {
            let rows_per_page = rows_fit.max(1);
            return SheetLayout {
                columns,
                tile_factor: f,
                tile_width: tw,
                tile_height: th,
                label_lines,
                rows_per_page,
                pages: rows_total.div_ceil(rows_per_page),
            };
        }
        // Shrink, but stop at the minimum when only paging is left to gain.
        let next = f * 0.94;
        f = if rows_fit >= 1 && natural_long * next < MIN_TILE_LONG_SIDE_PX as f64 {
            MIN_TILE_LONG_SIDE_PX as f64 / natural_long
        } else {
            next
        };
    }
}

/// `tiles` in a grid of `columns`, a label bar above each tile and `title` on top, as
/// one or more pages that each keep the limits ("page k/N" is added to the title when
/// there are several).
pub fn sheet_pages(tiles: &[(String, RgbImage)], columns: usize, title: &str) -> Vec<RgbImage> {
    let l = sheet_layout(tiles, columns, title);
    let per_page = l.columns * l.rows_per_page;
    let chunks: Vec<&[(String, RgbImage)]> = if tiles.is_empty() {
        vec![&[]]
    } else {
        tiles.chunks(per_page).collect()
    };
    let pages = chunks.len();
    chunks
        .into_iter()
        .enumerate()
        .map(|(k, chunk)| {
            let t = if pages > 1 {
                format!("{title} (page {}/{pages})", k + 1)
            } else {
                title.to_string()
            };
            draw_page(chunk, &l, &t)
        })
        .map(fit_to_limits)
        .collect()
}

fn draw_page(tiles: &[(String, RgbImage)], l: &SheetLayout, title: &str) -> RgbImage {
    let (tw, th) = (l.tile_width, l.tile_height);
    let label_h = l.label_lines as u32 * line_height() + LABEL_SCALE * 2;
    let width = l.columns as u32 * (tw + PAD) + PAD;
    let tl = title_lines(title, width);
    let title_h = tl.len() as u32 * line_height() + if title.is_empty() { 0 } else { 2 * PAD };
    let rows = tiles.len().div_ceil(l.columns).max(1) as u32;
    let height = title_h + rows * (th + label_h + PAD) + PAD;
    let mut out = RgbImage::from_pixel(width, height, SHEET_BACKGROUND);
    for (k, line) in tl.iter().enumerate() {
        draw_text(
            &mut out,
            PAD as i64,
            (PAD + k as u32 * line_height()) as i64,
            line,
            LABEL_SCALE,
            Rgb([0, 0, 0]),
        );
    }
    let cpl = chars_per_line(tw);
    for (i, (label, img)) in tiles.iter().enumerate() {
        let (c, r) = ((i % l.columns) as u32, (i / l.columns) as u32);
        let x = PAD + c * (tw + PAD);
        let y = title_h + PAD + r * (th + label_h + PAD);
        fill_rect(&mut out, x as i64, y as i64, tw, label_h, LABEL_BAR);
        for (k, line) in wrap_label(label, cpl, MAX_LABEL_LINES).iter().enumerate() {
            draw_text(
                &mut out,
                x as i64 + 2,
                (y + LABEL_SCALE + k as u32 * line_height()) as i64,
                line,
                LABEL_SCALE,
                Rgb([255, 255, 255]),
            );
        }
        let tile = scaled(img, l.tile_factor);
        // Never wider than the box (rounding), centred in it.
        let (dx, dy) = (
            tw.saturating_sub(tile.width()) / 2,
            th.saturating_sub(tile.height()) / 2,
        );
        image::imageops::replace(&mut out, &tile, (x + dx) as i64, (y + label_h + dy) as i64);
    }
    out
}

/// The width `text` needs at the label scale.
pub fn label_width(text: &str) -> u32 {
    text_width(text, LABEL_SCALE)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiles(n: usize, w: u32, h: u32, label: &str) -> Vec<(String, RgbImage)> {
        (0..n)
            .map(|k| {
                (
                    format!("{label} {k}"),
                    RgbImage::from_pixel(w, h, Rgb([(k * 20 % 256) as u8, 90, 200])),
                )
            })
            .collect()
    }

    #[test]
    fn fitting_keeps_both_limits_and_the_aspect() {
        for (w, h) in [
            (1920, 1080),
            (1292, 3080),
            (4000, 100),
            (1568, 733),
            (1100, 1100),
        ] {
            let img = fit_to_limits(RgbImage::new(w, h));
            assert!(
                within_limits(img.width(), img.height()),
                "{w}×{h} → {img:?}"
            );
            let (a, b) = (
                w as f64 / h as f64,
                img.width() as f64 / img.height() as f64,
            );
            assert!((a - b).abs() / a < 0.05, "{w}×{h}: aspect {a} → {b}");
        }
        // An image within the limits is untouched.
        let small = RgbImage::from_pixel(640, 480, Rgb([1, 2, 3]));
        assert_eq!(fit_to_limits(small.clone()), small);
        assert!(!within_limits(1569, 10) && !within_limits(1100, 1100));
    }

    #[test]
    fn a_tall_candidate_sheet_fits_the_limits_with_readable_tiles() {
        // The sheet that was 1292×3080: 6 finalists × (overlay, compare) of 640×480, 2 columns.
        let t = tiles(12, 640, 480, "#0 IoU 0.9812 yaw:12.5;pitch:-3;hinge:40");
        let pages = sheet_pages(&t, 2, "sweep 000010.png");
        for p in &pages {
            assert!(within_limits(p.width(), p.height()), "{p:?}");
        }
        let two = sheet_layout(&t, 2, "sweep 000010.png");
        assert!(
            two.tile_width.max(two.tile_height) >= MIN_TILE_LONG_SIDE_PX,
            "{two:?}"
        );
        assert_eq!(two.pages, pages.len());
        assert!(two.pages * two.rows_per_page * two.columns >= 12);
        // In four columns they fit one page with larger tiles.
        let four = sheet_layout(&t, 4, "sweep 000010.png");
        let one = sheet_pages(&t, 4, "sweep 000010.png");
        assert_eq!((one.len(), four.pages), (1, 1), "{four:?}");
        assert!(four.tile_width > two.tile_width, "{four:?} {two:?}");
        assert!(within_limits(one[0].width(), one[0].height()));
    }

    #[test]
    fn small_tiles_are_not_enlarged_and_labels_wrap_at_a_readable_size() {
        let t = tiles(3, 160, 120, "a long label that needs two lines");
        let l = sheet_layout(&t, 3, "");
        assert_eq!((l.tile_factor, l.tile_width, l.pages), (1.0, 160, 1));
        assert!(l.label_lines >= 2, "{l:?}");
        let lines = wrap_label("#2 IoU 0.9512 rz:90;rx:10;flip:y", 12, 4);
        assert!(lines.iter().all(|s| s.chars().count() <= 12), "{lines:?}");
        assert_eq!(
            lines.concat().replace(' ', ""),
            "#2IoU0.9512rz:90;rx:10;flip:y"
        );
        let cut = wrap_label(&"x".repeat(100), 10, 2);
        assert_eq!(cut.len(), 2);
        assert!(cut[1].ends_with(".."));
    }

    #[test]
    fn many_large_tiles_take_several_pages_each_within_the_limits() {
        let t = tiles(40, 1920, 1080, "frame");
        let pages = sheet_pages(&t, 4, "frames");
        let l = sheet_layout(&t, 4, "frames");
        assert_eq!(pages.len(), l.pages);
        assert!(pages.len() >= 2, "{l:?}");
        // Paging, not shrinking: the tiles stay at the minimum size.
        assert!(l.tile_width >= MIN_TILE_LONG_SIDE_PX - 1, "{l:?}");
        for p in &pages {
            assert!(within_limits(p.width(), p.height()), "{p:?}");
        }
    }

    #[test]
    fn a_legend_in_the_title_of_a_narrow_sheet_is_wrapped_whole() {
        let title = "compare (cropped): green both, yellow render only, magenta mask only, grey hand, blue render under the hand";
        let lines = title_lines(title, 320);
        assert!(lines.len() > 2, "{lines:?}");
        assert!(lines.iter().all(|l| !l.ends_with("..")), "{lines:?}");
        assert_eq!(lines.join(" "), title);
        // The sheet holds them: its height grows with the title's lines.
        let tiles = tiles(1, 300, 200, "000001");
        let short = sheet_pages(&tiles, 1, "compare");
        let long = sheet_pages(&tiles, 1, title);
        assert_eq!(long.len(), 1);
        assert!(long[0].height() > short[0].height());
    }
}
