//! The raw keyframe as a model should see it: cropped around the object's mask with a
//! margin, optionally outlined (the mask's boundary, the hand's, the model's), and zoomed,
//! never past the image limits.

use crate::sheet::{fit_to_limits, limit_factor, scaled};
use agentstar_mask::BitMask;
use image::{Rgb, RgbImage};

/// Outline of the object's mask on the frames view.
pub const MASK_OUTLINE: Rgb<u8> = Rgb([255, 40, 220]);
/// Outline of the hand mask (the don't-care region).
pub const HAND_OUTLINE: Rgb<u8> = Rgb([40, 220, 255]);
/// Outline of the rendered model.
pub const MODEL_OUTLINE: Rgb<u8> = Rgb([255, 220, 0]);

/// Largest zoom the frames view takes.
pub const MAX_ZOOM: f64 = 8.0;

/// What a frames view draws and how it crops.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameViewOptions {
    /// Margin around the mask's box, as a fraction of the box's longer side (at least 8 px).
    pub margin: f64,
    /// Scale of the crop (1 = the frame's pixels); shrunk when it would pass the limits.
    pub zoom: f64,
    /// Draw the mask's and the hand mask's boundaries.
    pub mask_outline: bool,
    /// The crop `[x0, y0, width, height]` in frame pixels, instead of the box around the
    /// mask (a detail to look at closely).
    pub window: Option<[u32; 4]>,
}

impl Default for FrameViewOptions {
    fn default() -> Self {
        FrameViewOptions {
            margin: 0.25,
            zoom: 1.0,
            mask_outline: false,
            window: None,
        }
    }
}

/// One frames view: the image and where it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameView {
    pub image: RgbImage,
    /// The crop in frame pixels: x0, y0, width, height.
    pub crop: [u32; 4],
    /// Output pixels per frame pixel after the zoom and the limits.
    pub zoom: f64,
    /// The mask was empty: the whole frame is shown.
    pub empty_mask: bool,
}

/// The crop around `mask` (and `extra`, e.g. the model's silhouette) with `margin`
/// (fraction of the box's longer side, at least 8 px), clamped to the frame.
pub fn crop_box(mask: &BitMask, extra: Option<&BitMask>, margin: f64) -> Option<[u32; 4]> {
    let (w, h) = (mask.width(), mask.height());
    let boxes = [mask.bbox(), extra.and_then(BitMask::bbox)];
    let (x0, y0, x1, y1) = boxes.iter().flatten().fold(
        (u32::MAX, u32::MAX, 0, 0),
        |(a, b, c, d), &(x0, y0, x1, y1)| (a.min(x0), b.min(y0), c.max(x1), d.max(y1)),
    );
    if x0 == u32::MAX {
        return None;
    }
    let side = (x1 - x0 + 1).max(y1 - y0 + 1) as f64;
    let m = (side * margin.max(0.0)).max(8.0).round() as i64;
    let cx0 = (x0 as i64 - m).max(0) as u32;
    let cy0 = (y0 as i64 - m).max(0) as u32;
    let cx1 = ((x1 as i64 + m) as u32).min(w - 1);
    let cy1 = ((y1 as i64 + m) as u32).min(h - 1);
    Some([cx0, cy0, cx1 - cx0 + 1, cy1 - cy0 + 1])
}

/// The `crop` (x0, y0, width, height) of `img`, its long side brought to `long_side_px` by
/// nearest-neighbour scaling (at most [`MAX_ZOOM`]): a comparison tile keeps its legend's
/// exact colours.
pub fn crop_zoomed(img: &RgbImage, crop: [u32; 4], long_side_px: u32) -> RgbImage {
    let [x0, y0, w, h] = crop;
    let sub = image::imageops::crop_imm(img, x0, y0, w, h).to_image();
    let factor = (long_side_px as f64 / w.max(h).max(1) as f64).min(MAX_ZOOM);
    let (tw, th) = (
        ((w as f64 * factor).round() as u32).max(1),
        ((h as f64 * factor).round() as u32).max(1),
    );
    image::imageops::resize(&sub, tw, th, image::imageops::FilterType::Nearest)
}

/// `crop` (x0, y0, width, height) widened about its centre to at least `min_aspect` times
/// its height, as far as a frame `frame_w` wide allows: a tall object's crop leaves room for
/// the labels a sheet writes under each tile (play-test 6: a bottle's sweep tiles cut their
/// orders after a few characters).
pub fn widened(crop: [u32; 4], min_aspect: f64, frame_w: u32) -> [u32; 4] {
    let [x0, y0, w, h] = crop;
    let want = ((h as f64 * min_aspect).ceil() as u32).min(frame_w);
    if w >= want {
        return crop;
    }
    let grow = want - w;
    let left = (x0).min(grow / 2 + grow % 2);
    let nx0 = x0 - left;
    // What does not fit on the left goes to the right, and back to the left at the border.
    let nx0 = nx0.min(frame_w - want);
    [nx0, y0, want, h]
}

/// Pixels of `m` inside the crop with a neighbour outside `m` (4-connected).
fn boundary(m: &BitMask, x: u32, y: u32) -> bool {
    if !m.get(x, y) {
        return false;
    }
    let (w, h) = (m.width(), m.height());
    x == 0
        || y == 0
        || x + 1 >= w
        || y + 1 >= h
        || !m.get(x - 1, y)
        || !m.get(x + 1, y)
        || !m.get(x, y - 1)
        || !m.get(x, y + 1)
}

/// The frames view of one keyframe: `frame` cropped around `mask` (and the model's
/// silhouette `model` when given, which is then outlined too), the outlines drawn one
/// output pixel wide after the zoom so they never hide more of the frame than needed.
pub fn frame_view(
    frame: &RgbImage,
    mask: &BitMask,
    hand: Option<&BitMask>,
    model: Option<&BitMask>,
    opts: &FrameViewOptions,
) -> FrameView {
    let around = crop_box(mask, model, opts.margin);
    let empty_mask = around.is_none() && opts.window.is_none();
    let [x0, y0, cw, ch] = opts
        .window
        .map(|[x, y, w, h]| {
            let (x, y) = (x.min(frame.width() - 1), y.min(frame.height() - 1));
            [
                x,
                y,
                w.min(frame.width() - x).max(1),
                h.min(frame.height() - y).max(1),
            ]
        })
        .or(around)
        .unwrap_or([0, 0, frame.width(), frame.height()]);
    let cut = image::imageops::crop_imm(frame, x0, y0, cw, ch).to_image();
    let zoom = opts.zoom.clamp(0.05, MAX_ZOOM);
    let zoom = zoom.min(zoom * limit_factor((cw as f64 * zoom) as u32, (ch as f64 * zoom) as u32));
    let mut image = scaled(&cut, zoom);
    let (ow, oh) = (image.width(), image.height());
    let outlines: Vec<(&BitMask, Rgb<u8>)> = [
        opts.mask_outline.then_some((mask, MASK_OUTLINE)),
        hand.filter(|_| opts.mask_outline)
            .map(|h| (h, HAND_OUTLINE)),
        model.map(|m| (m, MODEL_OUTLINE)),
    ]
    .into_iter()
    .flatten()
    .collect();
    if !outlines.is_empty() {
        // Each output pixel looks up its frame pixel; a boundary pixel of a mask marks it.
        // Under a zoom of 2 the marks are thickened to 3 px so they survive shrinking.
        let fy_of =
            |oy: u32| (y0 + ((oy as f64 + 0.5) * ch as f64 / oh as f64) as u32).min(y0 + ch - 1);
        let fx_of =
            |ox: u32| (x0 + ((ox as f64 + 0.5) * cw as f64 / ow as f64) as u32).min(x0 + cw - 1);
        for (m, c) in &outlines {
            let mut marks = vec![false; (ow * oh) as usize];
            for oy in 0..oh {
                let fy = fy_of(oy);
                for ox in 0..ow {
                    marks[(oy * ow + ox) as usize] = boundary(m, fx_of(ox), fy);
                }
            }
            let thick = zoom < 2.0;
            for oy in 0..oh {
                for ox in 0..ow {
                    let hit = if thick {
                        (oy.saturating_sub(1)..=(oy + 1).min(oh - 1)).any(|y| {
                            (ox.saturating_sub(1)..=(ox + 1).min(ow - 1))
                                .any(|x| marks[(y * ow + x) as usize])
                        })
                    } else {
                        marks[(oy * ow + ox) as usize]
                    };
                    if hit {
                        image.put_pixel(ox, oy, *c);
                    }
                }
            }
        }
    }
    FrameView {
        image: fit_to_limits(image),
        crop: [x0, y0, cw, ch],
        zoom,
        empty_mask,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sheet::within_limits;

    fn frame(w: u32, h: u32) -> RgbImage {
        RgbImage::from_fn(w, h, |x, y| Rgb([(x % 256) as u8, (y % 256) as u8, 7]))
    }

    #[test]
    fn a_tall_crop_is_widened_about_its_centre_within_the_frame() {
        // Room on both sides: centred.
        assert_eq!(
            widened([100, 0, 50, 120], 4.0 / 3.0, 640),
            [45, 0, 160, 120]
        );
        // At the right border: what does not fit there goes left; the crop stays inside.
        let c = widened([270, 10, 40, 200], 4.0 / 3.0, 320);
        assert_eq!(c, [53, 10, 267, 200]);
        assert!(c[0] <= 270 && c[0] + c[2] >= 310 && c[0] + c[2] <= 320);
        // Never wider than the frame; a wide crop is left as it is.
        assert_eq!(widened([0, 0, 10, 480], 4.0 / 3.0, 320), [0, 0, 320, 480]);
        assert_eq!(widened([5, 5, 300, 100], 4.0 / 3.0, 320), [5, 5, 300, 100]);
    }

    #[test]
    fn the_crop_holds_the_mask_with_its_margin_and_the_raw_pixels() {
        let f = frame(320, 240);
        let mask = BitMask::from_fn(320, 240, |x, y| {
            (100..140).contains(&x) && (50..70).contains(&y)
        });
        let v = frame_view(&f, &mask, None, None, &FrameViewOptions::default());
        // 40 px box, margin 0.25 → 10 px each side.
        assert_eq!(v.crop, [90, 40, 60, 40]);
        assert_eq!(v.image.dimensions(), (60, 40));
        assert_eq!(*v.image.get_pixel(0, 0), *f.get_pixel(90, 40));
        assert!(!v.empty_mask);
    }

    #[test]
    fn zoom_outlines_and_limits() {
        let f = frame(1920, 1080);
        let mask = BitMask::from_fn(1920, 1080, |x, y| {
            (900..1000).contains(&x) && (500..540).contains(&y)
        });
        let hand = BitMask::from_fn(1920, 1080, |x, y| {
            (960..1100).contains(&x) && (520..600).contains(&y)
        });
        let opts = FrameViewOptions {
            margin: 0.1,
            zoom: 4.0,
            mask_outline: true,
            window: None,
        };
        let v = frame_view(&f, &mask, Some(&hand), None, &opts);
        assert_eq!(v.zoom, 4.0);
        assert_eq!(v.image.width(), v.crop[2] * 4);
        let count = |c: Rgb<u8>| v.image.pixels().filter(|p| **p == c).count();
        assert!(count(MASK_OUTLINE) > 100 && count(HAND_OUTLINE) > 50);
        // A zoom that would pass the limits is reduced to them.
        let v = frame_view(
            &f,
            &mask,
            None,
            None,
            &FrameViewOptions {
                zoom: 8.0,
                margin: 1.0,
                ..opts
            },
        );
        assert!(
            within_limits(v.image.width(), v.image.height()),
            "{:?}",
            v.image.dimensions()
        );
        assert!(v.zoom < 8.0);
        // An empty mask shows the whole frame, within the limits.
        let v = frame_view(
            &f,
            &BitMask::new(1920, 1080),
            None,
            None,
            &FrameViewOptions::default(),
        );
        assert!(v.empty_mask && v.crop == [0, 0, 1920, 1080]);
        assert!(within_limits(v.image.width(), v.image.height()));
        // A window shows that box, zoomed, whatever the mask (clamped to the frame).
        let v = frame_view(
            &f,
            &mask,
            None,
            None,
            &FrameViewOptions {
                window: Some([950, 510, 12, 10]),
                zoom: 8.0,
                ..opts
            },
        );
        assert_eq!((v.crop, v.zoom), ([950, 510, 12, 10], 8.0));
        assert_eq!(v.image.dimensions(), (96, 80));
        // The window's middle, not the mask's: the frame's gradient there (x, y mod 256).
        let mid = v.image.get_pixel(48, 40);
        assert!(
            (mid[0] as i32 - (956 % 256)).abs() <= 2 && (mid[1] as i32 - (515 % 256)).abs() <= 2,
            "{mid:?}"
        );
        let v = frame_view(
            &f,
            &mask,
            None,
            None,
            &FrameViewOptions {
                window: Some([1910, 1070, 40, 40]),
                zoom: 1.0,
                ..opts
            },
        );
        assert_eq!(v.crop, [1910, 1070, 10, 10]);
    }

    #[test]
    fn a_zoomed_crop_keeps_exact_colours_and_its_long_side() {
        let mut img = RgbImage::from_pixel(640, 480, Rgb([0, 0, 0]));
        for y in 200..240 {
            for x in 300..320 {
                img.put_pixel(x, y, Rgb([40, 190, 70]));
            }
        }
        // A 40 × 60 crop around the patch, its long side brought to 300 (×5).
        let tile = crop_zoomed(&img, [290, 190, 40, 60], 300);
        assert_eq!(tile.dimensions(), (200, 300));
        // Nearest neighbour: only the two colours, the patch where it was.
        assert!(tile
            .pixels()
            .all(|p| *p == Rgb([0, 0, 0]) || *p == Rgb([40, 190, 70])));
        assert_eq!(*tile.get_pixel(100, 150), Rgb([40, 190, 70]));
        assert_eq!(*tile.get_pixel(5, 5), Rgb([0, 0, 0]));
        // A tiny crop stops at the largest zoom.
        assert_eq!(crop_zoomed(&img, [0, 0, 10, 5], 400).dimensions(), (80, 40));
    }
}
