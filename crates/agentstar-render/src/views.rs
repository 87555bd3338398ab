//! Images for people and models: the shaded render, the render over the frame, the
//! silhouette comparison with its legend, the part-id view, turntable cameras and contact
//! sheets. Labels sit in bars beside the pixels, never over them.

use crate::full::{RenderBuffers, NO_PART};
use crate::sheet::{limit_factor, scaled, within_limits, wrap_label, LABEL_SCALE};
use crate::text::{draw_text, fill_rect, scale_for_width, text_width};
use agentstar_geom::camera::look_at;
use agentstar_geom::pose::{Rigid, Similarity};
use agentstar_geom::{ObjectModel, PinholeCamera, Point3, UnitQuaternion, Vector3};
use agentstar_mask::BitMask;
use image::{Rgb, RgbImage, Rgba, RgbaImage};

/// Colours of the silhouette comparison; the legend drawn on the images and the one in
/// TASK.md are both generated from [`COMPARE_LEGEND`], which holds these constants.
pub const BOTH: Rgb<u8> = Rgb([40, 190, 70]);
pub const RENDER_ONLY: Rgb<u8> = Rgb([240, 210, 40]);
pub const MASK_ONLY: Rgb<u8> = Rgb([220, 40, 200]);
pub const HAND: Rgb<u8> = Rgb([120, 120, 120]);
pub const RENDER_IN_HAND: Rgb<u8> = Rgb([60, 110, 230]);
pub const BACKGROUND: Rgb<u8> = Rgb([18, 18, 22]);
/// Background of turntable views: light, so that dark parts stand out.
pub const TURNTABLE_BACKGROUND: Rgb<u8> = Rgb([236, 236, 240]);

/// One colour of a legend: the colour, its common name, what it means on the image and
/// its short label on the image's own legend.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LegendColour {
    pub colour: Rgb<u8>,
    pub name: &'static str,
    pub label: &'static str,
    pub meaning: &'static str,
    /// Shown only when the frame has a hand mask.
    pub hand_only: bool,
    /// Drawn as a swatch in the image's legend (the background is not).
    pub swatch: bool,
}

/// The silhouette comparison's colours, in legend order.
pub const COMPARE_LEGEND: [LegendColour; 6] = [
    LegendColour {
        colour: BOTH,
        name: "green",
        label: "both",
        meaning: "model and mask agree",
        hand_only: false,
        swatch: true,
    },
    LegendColour {
        colour: RENDER_ONLY,
        name: "yellow",
        label: "render only (extra)",
        meaning: "model outside the mask: too big or misplaced there",
        hand_only: false,
        swatch: true,
    },
    LegendColour {
        colour: MASK_ONLY,
        name: "magenta",
        label: "mask only (missing)",
        meaning: "mask not covered by the model: too small or misplaced there",
        hand_only: false,
        swatch: true,
    },
    LegendColour {
        colour: HAND,
        name: "grey",
        label: "hand (ignored)",
        meaning: "hand mask, not scored",
        hand_only: true,
        swatch: true,
    },
    LegendColour {
        colour: RENDER_IN_HAND,
        name: "blue",
        label: "render under hand",
        meaning: "model under the hand (not scored: the hand may hide it)",
        hand_only: true,
        swatch: true,
    },
    LegendColour {
        colour: BACKGROUND,
        name: "near-black",
        label: "background",
        meaning: "neither model nor mask",
        hand_only: false,
        swatch: false,
    },
];

/// Options of the shaded render.
#[derive(Debug, Clone, Copy)]
pub struct ShadeOptions {
    /// Darken pixels on part boundaries and depth discontinuities.
    pub outlines: bool,
}

impl Default for ShadeOptions {
    fn default() -> Self {
        ShadeOptions { outlines: true }
    }
}

fn to_u8(v: f32) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// Flat part colours lit by one light near the camera plus ambient light; transparent
/// where nothing is rendered. Textures and vertex colours are not drawn: views of a model
/// use [`shade_model`].
pub fn shade(buffers: &RenderBuffers, colors: &[[f32; 3]], opts: ShadeOptions) -> RgbaImage {
    shade_with(buffers, opts, |_, part| {
        colors.get(part as usize).copied().unwrap_or([0.7; 3])
    })
}

/// The model's surface (textures, vertex colours, part colours; see
/// [`crate::surface::surface_colors`]) lit as [`shade`] lights it. `instances` are the
/// ones `buffers` was rendered from, `camera` the camera they were rendered with.
pub fn shade_model(
    model: &agentstar_geom::ObjectModel,
    instances: &[crate::Instance<'_>],
    camera: &agentstar_geom::PinholeCamera,
    buffers: &RenderBuffers,
    opts: ShadeOptions,
) -> RgbaImage {
    if model.parts.iter().all(|p| p.surface.is_none()) {
        let colors: Vec<[f32; 3]> = model.parts.iter().map(|p| p.color).collect();
        return shade(buffers, &colors, opts);
    }
    let colors = crate::surface::surface_colors(model, instances, camera, buffers);
    shade_with(buffers, opts, |k, _| colors[k].unwrap_or([0.7; 3]))
}

fn shade_with(
    buffers: &RenderBuffers,
    opts: ShadeOptions,
    color_of: impl Fn(usize, u16) -> [f32; 3],
) -> RgbaImage {
    let (w, h) = (buffers.width, buffers.height);
    let light = {
        let l = [-0.35f32, -0.55, -1.0];
        let n = (l[0] * l[0] + l[1] * l[1] + l[2] * l[2]).sqrt();
        [l[0] / n, l[1] / n, l[2] / n]
    };
    let mut img = RgbaImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let k = (y * w + x) as usize;
            let part = buffers.part[k];
            if part == NO_PART {
                continue;
            }
            let c = color_of(k, part);
            let n = buffers.normal[k];
            let lambert = (n[0] * light[0] + n[1] * light[1] + n[2] * light[2]).max(0.0);
            let mut f = 0.35 + 0.65 * lambert;
            if opts.outlines && is_edge(buffers, x, y) {
                f *= 0.35;
            }
            img.put_pixel(
                x,
                y,
                Rgba([to_u8(c[0] * f), to_u8(c[1] * f), to_u8(c[2] * f), 255]),
            );
        }
    }
    img
}

fn is_edge(b: &RenderBuffers, x: u32, y: u32) -> bool {
    let k = (y * b.width + x) as usize;
    let (p, z) = (b.part[k], b.depth[k]);
    let neighbours = [
        (x.wrapping_sub(1), y),
        (x + 1, y),
        (x, y.wrapping_sub(1)),
        (x, y + 1),
    ];
    neighbours.iter().any(|&(nx, ny)| {
        if nx >= b.width || ny >= b.height {
            return false;
        }
        let j = (ny * b.width + nx) as usize;
        b.part[j] != p || (b.depth[j] - z).abs() > 0.03 * z
    })
}

/// The render blended over the frame (`opacity` of the render where it covers).
pub fn overlay(frame: &RgbImage, render: &RgbaImage, opacity: f32) -> RgbImage {
    let mut out = frame.clone();
    for (x, y, p) in render.enumerate_pixels() {
        if p[3] == 0 || x >= out.width() || y >= out.height() {
            continue;
        }
        let a = opacity * p[3] as f32 / 255.0;
        let f = out.get_pixel(x, y);
        let mix = |i: usize| (f[i] as f32 * (1.0 - a) + p[i] as f32 * a + 0.5) as u8;
        out.put_pixel(x, y, Rgb([mix(0), mix(1), mix(2)]));
    }
    out
}

/// Adds a bar below `img` with coloured legend swatches and a title, drawn at the label
/// scale; the canvas is widened (centred) when the entries need more room than a small
/// image gives, and the image is shrunk first when the whole would pass the limits, so the
/// legend itself is never scaled.
pub fn with_legend(img: &RgbImage, title: &str, entries: &[(Rgb<u8>, String)]) -> RgbImage {
    let scale = LABEL_SCALE;
    let line = 10 * scale;
    let entry_w = |label: &str| 10 * scale + text_width(label, scale) + 8 * scale;
    let widest = entries.iter().map(|(_, l)| entry_w(l)).max().unwrap_or(0) + 2 * scale;
    let layout = |width: u32| {
        let mut rows: Vec<Vec<(Rgb<u8>, &str)>> = vec![vec![]];
        let mut x = 2 * scale;
        for (c, label) in entries {
            let wdt = entry_w(label);
            if x + wdt > width && !rows.last().is_some_and(|r| r.is_empty()) {
                rows.push(vec![]);
                x = 2 * scale;
            }
            if let Some(r) = rows.last_mut() {
                r.push((*c, label.as_str()));
            }
            x += wdt;
        }
        let titles = if title.is_empty() {
            vec![]
        } else {
            // Up to 4 lines: a cropped image can be narrow, and its title carries the figures.
            wrap_label(title, ((width - 4 * scale) / (8 * scale)) as usize, 4)
        };
        let bar = (rows.len() as u32 + titles.len() as u32) * (line + 2 * scale) + 2 * scale;
        (rows, titles, bar)
    };
    // Shrink the image until image and bar keep the limits together.
    let mut img = std::borrow::Cow::Borrowed(img);
    loop {
        let width = img.width().max(widest).max(16 * 8 * scale / 2);
        let (_, _, bar) = layout(width);
        if within_limits(width, img.height() + bar) || img.width() < 64 {
            break;
        }
        let f = limit_factor(width, img.height() + bar) * 0.995;
        img = std::borrow::Cow::Owned(scaled(&img, f.min(0.98)));
    }
    let width = img.width().max(widest).max(16 * 8 * scale / 2);
    let (rows, titles, bar) = layout(width);
    let mut out = RgbImage::from_pixel(width, img.height() + bar, Rgb([250, 250, 250]));
    image::imageops::replace(&mut out, &*img, ((width - img.width()) / 2) as i64, 0);
    let mut y = img.height() as i64 + 2 * scale as i64;
    for t in titles {
        draw_text(&mut out, 2 * scale as i64, y, &t, scale, Rgb([0, 0, 0]));
        y += (line + 2 * scale) as i64;
    }
    for row in rows {
        let mut x = 2 * scale as i64;
        for (c, label) in row {
            fill_rect(&mut out, x, y, 8 * scale, 8 * scale, c);
            x += 10 * scale as i64;
            draw_text(&mut out, x, y, label, scale, Rgb([0, 0, 0]));
            x += (text_width(label, scale) + 8 * scale) as i64;
        }
        y += (line + 2 * scale) as i64;
    }
    out
}

/// Pixel counts of a silhouette comparison.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ComparisonCounts {
    pub both: u64,
    pub render_only: u64,
    pub mask_only: u64,
    pub hand: u64,
    pub render_in_hand: u64,
}

/// The silhouette comparison: both, render only (extra), mask only (missing), the hand's
/// don't-care region and the render inside it, each its own colour, over a dark background.
pub fn silhouette_comparison(
    render: &BitMask,
    mask: &BitMask,
    hand: Option<&BitMask>,
) -> (RgbImage, ComparisonCounts) {
    let (w, h) = (mask.width(), mask.height());
    let mut img = RgbImage::from_pixel(w, h, BACKGROUND);
    let mut n = ComparisonCounts::default();
    for y in 0..h {
        for x in 0..w {
            let r = render.get(x, y);
            let m = mask.get(x, y);
            let in_hand = hand.is_some_and(|hm| hm.get(x, y));
            let c = if in_hand {
                if r {
                    n.render_in_hand += 1;
                    RENDER_IN_HAND
                } else {
                    n.hand += 1;
                    HAND
                }
            } else {
                match (r, m) {
                    (true, true) => {
                        n.both += 1;
                        BOTH
                    }
                    (true, false) => {
                        n.render_only += 1;
                        RENDER_ONLY
                    }
                    (false, true) => {
                        n.mask_only += 1;
                        MASK_ONLY
                    }
                    (false, false) => continue,
                }
            };
            img.put_pixel(x, y, c);
        }
    }
    (img, n)
}

/// The legend entries of the silhouette comparison (from [`COMPARE_LEGEND`]).
pub fn comparison_legend(has_hand: bool) -> Vec<(Rgb<u8>, String)> {
    COMPARE_LEGEND
        .iter()
        .filter(|e| e.swatch && (has_hand || !e.hand_only))
        .map(|e| (e.colour, e.label.to_string()))
        .collect()
}

/// The common name of a colour, from its hue, saturation and value: near-black, grey,
/// white, red, orange, yellow, green, cyan, blue, purple or magenta. Tests hold every
/// legend's names to the colours they describe.
pub fn colour_name(c: Rgb<u8>) -> &'static str {
    let [r, g, b] = c.0.map(|v| v as f64 / 255.0);
    let (max, min) = (r.max(g).max(b), r.min(g).min(b));
    let d = max - min;
    if max < 0.15 {
        return "near-black";
    }
    if d / max < 0.15 {
        return if max > 0.9 { "white" } else { "grey" };
    }
    let h = if max == r {
        60.0 * ((g - b) / d).rem_euclid(6.0)
    } else if max == g {
        60.0 * ((b - r) / d + 2.0)
    } else {
        60.0 * ((r - g) / d + 4.0)
    };
    match h {
        h if !(15.0..340.0).contains(&h) => "red",
        h if h < 45.0 => "orange",
        h if h < 70.0 => "yellow",
        h if h < 170.0 => "green",
        h if h < 200.0 => "cyan",
        h if h < 260.0 => "blue",
        h if h < 290.0 => "purple",
        _ => "magenta",
    }
}

/// `#rrggbb` of a colour.
pub fn hex(c: Rgb<u8>) -> String {
    format!("#{:02x}{:02x}{:02x}", c[0], c[1], c[2])
}

/// A distinct flat colour for part `i`.
pub fn id_color(i: usize) -> Rgb<u8> {
    const P: [[u8; 3]; 12] = [
        [230, 25, 75],
        [60, 180, 75],
        [255, 225, 25],
        [0, 130, 200],
        [245, 130, 48],
        [145, 30, 180],
        [70, 240, 240],
        [240, 50, 230],
        [210, 245, 60],
        [250, 190, 212],
        [0, 128, 128],
        [170, 110, 40],
    ];
    Rgb(P[i % P.len()])
}

/// What the part-id view shows of one part.
#[derive(Debug, Clone, PartialEq)]
pub struct PartVisibility {
    pub name: String,
    pub pixels: u64,
    /// Mean pixel position of the visible pixels.
    pub centroid: Option<[f64; 2]>,
}

/// Every part in its own flat colour, and the visible pixel count of each part.
pub fn part_id_view(buffers: &RenderBuffers, names: &[String]) -> (RgbImage, Vec<PartVisibility>) {
    let mut img = RgbImage::from_pixel(buffers.width, buffers.height, BACKGROUND);
    let mut acc = vec![(0u64, 0f64, 0f64); names.len()];
    for y in 0..buffers.height {
        for x in 0..buffers.width {
            let p = buffers.part[(y * buffers.width + x) as usize];
            if p == NO_PART {
                continue;
            }
            img.put_pixel(x, y, id_color(p as usize));
            if let Some(a) = acc.get_mut(p as usize) {
                a.0 += 1;
                a.1 += x as f64 + 0.5;
                a.2 += y as f64 + 0.5;
            }
        }
    }
    let vis = names
        .iter()
        .zip(&acc)
        .map(|(n, &(c, sx, sy))| PartVisibility {
            name: n.clone(),
            pixels: c,
            centroid: (c > 0).then(|| [sx / c as f64, sy / c as f64]),
        })
        .collect();
    (img, vis)
}

/// One turntable viewpoint.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TurntableView {
    pub azimuth_deg: f64,
    pub elevation_deg: f64,
}

/// The `sphere8` set: a ring at 20° elevation (azimuths 0/90/180/270), a raised pair at
/// +60° (45/225) and a dropped pair at −30° (135/315).
pub fn sphere8() -> Vec<TurntableView> {
    let mut v: Vec<TurntableView> = [0.0, 90.0, 180.0, 270.0]
        .iter()
        .map(|&a| TurntableView {
            azimuth_deg: a,
            elevation_deg: 20.0,
        })
        .collect();
    v.extend([45.0, 225.0].iter().map(|&a| TurntableView {
        azimuth_deg: a,
        elevation_deg: 60.0,
    }));
    v.extend([135.0, 315.0].iter().map(|&a| TurntableView {
        azimuth_deg: a,
        elevation_deg: -30.0,
    }));
    v
}

/// `camera_from_object` for a turntable view. The object is oriented as in the reference
/// view (`reference_rotation`) and centred on its pivot; azimuth 0, elevation 0 looks from
/// the reference camera; elevation is toward the reference camera's up (−Y).
pub fn turntable_pose(
    model: &ObjectModel,
    states: &[f64],
    reference_rotation: &UnitQuaternion,
    view: &TurntableView,
    fov_x_deg: f64,
) -> Similarity {
    let bounds = model.posed_bounds(states);
    let pivot = bounds.center();
    let radius = (bounds.extent().norm() * 0.5).max(1e-6);
    let distance = radius / (fov_x_deg.to_radians() * 0.5).sin() * 1.05;
    let (az, el) = (
        view.azimuth_deg.to_radians(),
        view.elevation_deg.to_radians(),
    );
    let up = Vector3::new(0.0, -1.0, 0.0);
    let eye = Point3::from(
        (Vector3::x() * az.sin() * el.cos() - Vector3::z() * az.cos() * el.cos() + up * el.sin())
            * distance,
    );
    let camera_from_ref: Rigid = look_at(&eye, &Point3::origin(), &up);
    // Reference frame: object rotated by the reference rotation, pivot at the origin.
    let ref_from_object = Similarity {
        scale: 1.0,
        rotation: *reference_rotation,
        translation: -(reference_rotation * pivot.coords),
    };
    Similarity::from_rigid(&camera_from_ref).compose(&ref_from_object)
}

/// Lays tiles out in a grid with a label bar above each tile.
pub fn contact_sheet(tiles: &[(String, RgbImage)], columns: usize, title: &str) -> RgbImage {
    let columns = columns.max(1);
    let tw = tiles.iter().map(|t| t.1.width()).max().unwrap_or(64);
    let th = tiles.iter().map(|t| t.1.height()).max().unwrap_or(64);
    let scale = scale_for_width(tw).max(1);
    let label_h = 12 * scale;
    let pad = 4;
    let rows = tiles.len().div_ceil(columns).max(1) as u32;
    let title_h = if title.is_empty() { 0 } else { 14 * scale };
    let width = columns as u32 * (tw + pad) + pad;
    let height = title_h + rows * (th + label_h + pad) + pad;
    let mut out = RgbImage::from_pixel(width, height, Rgb([235, 235, 235]));
    if !title.is_empty() {
        draw_text(
            &mut out,
            pad as i64,
            3 * scale as i64,
            title,
            scale,
            Rgb([0, 0, 0]),
        );
    }
    for (i, (label, img)) in tiles.iter().enumerate() {
        let (c, r) = ((i % columns) as u32, (i / columns) as u32);
        let x = pad + c * (tw + pad);
        let y = title_h + pad + r * (th + label_h + pad);
        fill_rect(&mut out, x as i64, y as i64, tw, label_h, Rgb([40, 40, 48]));
        let max_chars = (tw / (8 * scale)) as usize;
        let shown: String = label.chars().take(max_chars).collect();
        draw_text(
            &mut out,
            x as i64 + 2,
            y as i64 + 2 * scale as i64,
            &shown,
            scale,
            Rgb([255, 255, 255]),
        );
        image::imageops::replace(&mut out, img, x as i64, (y + label_h) as i64);
    }
    out
}

/// The frame and the model side by side over one crop (`[x0, y0, w, h]` in frame pixels,
/// scaled by `zoom`): the frame's own pixels on the left, the render opaque over `background`
/// on the right, with a gap of [`SIDE_GAP_PX`]. Nothing of one shows through the other, so
/// a print on the model can be compared with the print in the frame (an overlay blends
/// them). Where `hand` (the frame's hand mask) covers the frame, both halves are hatched in
/// [`SIDE_HAND_HATCH`], so the part of the model the hand hides in the frame shows as
/// such; every other pixel is as without hands.
pub fn side_by_side(
    frame: &RgbImage,
    render: &RgbaImage,
    hand: Option<&BitMask>,
    crop: [u32; 4],
    zoom: f64,
    background: Rgb<u8>,
) -> RgbImage {
    let [x0, y0, w, h] = crop;
    let cut = |img: &RgbImage| -> RgbImage {
        let (x0, y0) = (x0.min(img.width()), y0.min(img.height()));
        let w = w.min(img.width() - x0).max(1);
        let h = h.min(img.height() - y0).max(1);
        let part = image::imageops::crop_imm(img, x0, y0, w, h).to_image();
        let mut out = scaled(&part, zoom);
        if let Some(hand) = hand {
            hatch_hand(&mut out, hand, [x0, y0, w, h]);
        }
        out
    };
    let left = cut(frame);
    let right = cut(&flatten(render, background));
    let mut out = RgbImage::from_pixel(
        left.width() + SIDE_GAP_PX + right.width(),
        left.height().max(right.height()),
        Rgb([255, 255, 255]),
    );
    image::imageops::replace(&mut out, &left, 0, 0);
    image::imageops::replace(&mut out, &right, (left.width() + SIDE_GAP_PX) as i64, 0);
    out
}

/// The white gap between the two halves of [`side_by_side`], in pixels.
pub const SIDE_GAP_PX: u32 = 6;

/// The hand's hatching in [`side_by_side`]: the cyan the frames view outlines hands in,
/// a colour objects rarely have.
pub const SIDE_HAND_HATCH: Rgb<u8> = crate::frames::HAND_OUTLINE;

/// Hatches the pixels of `img` (the crop `[x0, y0, w, h]` of a frame, scaled to `img`'s
/// size) whose frame pixel `hand` covers: solid stripes of [`SIDE_HAND_HATCH`] on the
/// diagonal, the pixels between them tinted half way to it. Each output pixel reads its
/// nearest frame pixel, so the hatching stops at the hand's edge whatever the zoom.
fn hatch_hand(img: &mut RgbImage, hand: &BitMask, [x0, y0, w, h]: [u32; 4]) {
    let (out_w, out_h) = img.dimensions();
    for oy in 0..out_h {
        let sy = y0 + ((oy as u64 * h as u64) / out_h as u64) as u32;
        for ox in 0..out_w {
            let sx = x0 + ((ox as u64 * w as u64) / out_w as u64) as u32;
            if !(sx < hand.width() && sy < hand.height() && hand.get(sx, sy)) {
                continue;
            }
            let p = img.get_pixel_mut(ox, oy);
            if ((ox + oy) / 3) % 3 == 0 {
                *p = SIDE_HAND_HATCH;
            } else {
                for c in 0..3 {
                    p[c] = ((p[c] as u16 + SIDE_HAND_HATCH[c] as u16) / 2) as u8;
                }
            }
        }
    }
}

/// Composites an RGBA render over a solid background.
pub fn flatten(render: &RgbaImage, background: Rgb<u8>) -> RgbImage {
    RgbImage::from_fn(render.width(), render.height(), |x, y| {
        let p = render.get_pixel(x, y);
        let a = p[3] as f32 / 255.0;
        let m = |i: usize| (p[i] as f32 * a + background[i] as f32 * (1.0 - a) + 0.5) as u8;
        Rgb([m(0), m(1), m(2)])
    })
}

/// A square camera for turntables.
pub fn turntable_camera(size_px: u32, fov_x_deg: f64) -> PinholeCamera {
    PinholeCamera::with_fov(fov_x_deg, size_px, size_px)
}

/// A 2-D score field as an image: one cell per grid point, dark (low) to bright (high), the
/// best cell outlined, axis values and the score range written beside the grid.
pub fn heat_map(
    a_name: &str,
    a: &[f64],
    b_name: &str,
    b: &[f64],
    scores: &[Vec<Option<f64>>],
) -> RgbImage {
    let cell = (360 / a.len().max(b.len()).max(1)).clamp(12, 48) as u32;
    let (left, top) = (80u32, 40u32);
    let w = left + cell * b.len() as u32 + 20;
    let h = top + cell * a.len() as u32 + 40;
    let mut img = RgbImage::from_pixel(w.max(320), h, Rgb([255, 255, 255]));
    let vals: Vec<f64> = scores.iter().flatten().flatten().copied().collect();
    let lo = vals.iter().copied().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mut best = None;
    for (i, row) in scores.iter().enumerate() {
        for (j, v) in row.iter().enumerate() {
            let c = match v {
                Some(v) => {
                    let t = if hi > lo {
                        ((v - lo) / (hi - lo)) as f32
                    } else {
                        1.0
                    };
                    if best.is_none_or(|(_, _, bv)| *v > bv) {
                        best = Some((i, j, *v));
                    }
                    Rgb([
                        to_u8(0.1 + 0.9 * t),
                        to_u8(0.15 + 0.75 * t * t),
                        to_u8(0.35 * (1.0 - t)),
                    ])
                }
                None => Rgb([200, 200, 200]),
            };
            fill_rect(
                &mut img,
                (left + j as u32 * cell) as i64,
                (top + i as u32 * cell) as i64,
                cell - 1,
                cell - 1,
                c,
            );
        }
    }
    if let Some((i, j, _)) = best {
        let (x, y) = (
            (left + j as u32 * cell) as i64,
            (top + i as u32 * cell) as i64,
        );
        for k in 0..cell as i64 {
            for (px, py) in [
                (x + k, y),
                (x + k, y + cell as i64 - 2),
                (x, y + k),
                (x + cell as i64 - 2, y + k),
            ] {
                if px >= 0 && py >= 0 && (px as u32) < img.width() && (py as u32) < img.height() {
                    img.put_pixel(px as u32, py as u32, Rgb([0, 160, 255]));
                }
            }
        }
    }
    draw_text(
        &mut img,
        4,
        4,
        &format!("rows {a_name}, columns {b_name}; score {lo:.4} .. {hi:.4}"),
        1,
        Rgb([0, 0, 0]),
    );
    for (i, v) in a.iter().enumerate() {
        draw_text(
            &mut img,
            4,
            (top + i as u32 * cell + cell / 2 - 4) as i64,
            &format!("{v:.3}"),
            1,
            Rgb([0, 0, 0]),
        );
    }
    for (j, v) in b
        .iter()
        .enumerate()
        .step_by((64 / cell as usize).max(1) + 1)
    {
        draw_text(
            &mut img,
            (left + j as u32 * cell) as i64,
            (top + a.len() as u32 * cell + 6) as i64,
            &format!("{v:.3}"),
            1,
            Rgb([0, 0, 0]),
        );
    }
    img
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn side_by_side_shows_the_frame_and_the_opaque_render_apart() {
        // A grey frame with a red square; a render with a blue square half transparent.
        let frame = RgbImage::from_fn(40, 30, |x, y| {
            if (10..20).contains(&x) && (10..20).contains(&y) {
                Rgb([200, 0, 0])
            } else {
                Rgb([90, 90, 90])
            }
        });
        let render = RgbaImage::from_fn(40, 30, |x, y| {
            if (12..22).contains(&x) && (8..18).contains(&y) {
                Rgba([0, 0, 255, 255])
            } else {
                Rgba([0, 0, 0, 0])
            }
        });
        let bg = Rgb([255, 255, 255]);
        let img = side_by_side(&frame, &render, None, [8, 6, 16, 16], 2.0, bg);
        assert_eq!(img.dimensions(), (32 + SIDE_GAP_PX + 32, 32));
        // Left: the frame's red, untouched by the render's blue.
        assert_eq!(*img.get_pixel(2 * (15 - 8), 2 * (15 - 6)), Rgb([200, 0, 0]));
        // Right: the render opaque, the background where it is empty.
        let right = 32 + SIDE_GAP_PX;
        assert_eq!(
            *img.get_pixel(right + 2 * (15 - 8), 2 * (10 - 6)),
            Rgb([0, 0, 255])
        );
        assert_eq!(*img.get_pixel(right + 1, 30), bg);
        // A crop past the edge is cut at the edge.
        let edge = side_by_side(&frame, &render, None, [30, 20, 20, 20], 1.0, bg);
        assert_eq!(edge.dimensions(), (10 + SIDE_GAP_PX + 10, 10));
    }

    #[test]
    fn side_by_side_hatches_the_hand_on_both_halves_and_nothing_else() {
        // A frame of smooth shades (so no pixel is the hatch's cyan), a render with an
        // opaque square, and a hand over a corner of both.
        let frame = RgbImage::from_fn(40, 30, |x, y| Rgb([(4 * x) as u8, (5 * y) as u8, 90]));
        let render = RgbaImage::from_fn(40, 30, |x, y| {
            if (12..28).contains(&x) && (8..22).contains(&y) {
                Rgba([200, 60, 30, 255])
            } else {
                Rgba([0, 0, 0, 0])
            }
        });
        let hand = BitMask::from_fn(40, 30, |x, y| (20..34).contains(&x) && (4..16).contains(&y));
        let bg = Rgb([255, 255, 255]);
        let crop = [8, 2, 30, 24];
        for zoom in [1.0, 2.0, 3.0] {
            let bare = side_by_side(&frame, &render, None, crop, zoom, bg);
            let hatched = side_by_side(&frame, &render, Some(&hand), crop, zoom, bg);
            assert_eq!(bare.dimensions(), hatched.dimensions());
            let half = (bare.width() - SIDE_GAP_PX) / 2;
            let (mut differ, mut hand_px) = (0, 0);
            for (ox, oy, p) in hatched.enumerate_pixels() {
                // The frame pixel this output pixel shows, on either half.
                let local = if ox < half {
                    Some(ox)
                } else if ox >= half + SIDE_GAP_PX {
                    Some(ox - half - SIDE_GAP_PX)
                } else {
                    None
                };
                let under_hand = local.is_some_and(|lx| {
                    let sx = crop[0] + (lx as u64 * crop[2] as u64 / half as u64) as u32;
                    let sy = crop[1] + (oy as u64 * crop[3] as u64 / bare.height() as u64) as u32;
                    hand.get(sx, sy)
                });
                let same = p == bare.get_pixel(ox, oy);
                if under_hand {
                    hand_px += 1;
                    differ += usize::from(!same);
                    assert!(!same, "zoom {zoom}: hand pixel ({ox}, {oy}) unmarked");
                } else {
                    assert!(same, "zoom {zoom}: pixel ({ox}, {oy}) off the hand changed");
                }
            }
            // Both halves hold hand pixels: the frame's and the model's.
            assert!(hand_px > 0 && differ == hand_px, "{hand_px} {differ}");
            let right_hand = (half + SIDE_GAP_PX..hatched.width()).any(|ox| {
                hatched.get_pixel(ox, bare.height() / 3) != bare.get_pixel(ox, bare.height() / 3)
            });
            assert!(right_hand, "zoom {zoom}: the model's half is not hatched");
        }
    }

    #[test]
    fn comparison_counts_every_category() {
        let mask = BitMask::from_fn(10, 1, |x, _| x < 5);
        let render = BitMask::from_fn(10, 1, |x, _| (3..8).contains(&x));
        let hand = BitMask::from_fn(10, 1, |x, _| x >= 7);
        let (img, n) = silhouette_comparison(&render, &mask, Some(&hand));
        assert_eq!(
            n,
            ComparisonCounts {
                both: 2,
                render_only: 2,
                mask_only: 3,
                hand: 2,
                render_in_hand: 1
            }
        );
        assert_eq!(*img.get_pixel(0, 0), MASK_ONLY);
        assert_eq!(*img.get_pixel(3, 0), BOTH);
        assert_eq!(*img.get_pixel(7, 0), RENDER_IN_HAND);
        let with = with_legend(&img, "frame 000000", &comparison_legend(true));
        assert!(with.height() > img.height());
    }

    #[test]
    fn every_legend_name_describes_its_colour() {
        for e in COMPARE_LEGEND {
            assert_eq!(colour_name(e.colour), e.name, "{e:?}");
        }
        // The names are distinct, so a reader can tell the colours apart by name.
        let mut names: Vec<&str> = COMPARE_LEGEND.iter().map(|e| e.name).collect();
        names.sort_unstable();
        names.dedup();
        assert_eq!(names.len(), COMPARE_LEGEND.len());
        assert_eq!(colour_name(Rgb([255, 0, 0])), "red");
        assert_eq!(colour_name(Rgb([250, 250, 250])), "white");
        assert_eq!(hex(MASK_ONLY), "#dc28c8");
        assert_eq!(colour_name(TURNTABLE_BACKGROUND), "white");
    }

    #[test]
    fn a_legend_is_readable_on_a_small_image_and_keeps_the_limits_on_a_large_one() {
        let small = RgbImage::from_pixel(160, 120, BACKGROUND);
        let out = with_legend(
            &small,
            "000000.png IoU 0.9 raw 0.9",
            &comparison_legend(true),
        );
        // Widened so that the longest entry fits at the label scale.
        assert!(out.width() > 160 && out.width() >= text_width("render only (extra)", 2));
        assert_eq!(*out.get_pixel((out.width() - 160) / 2, 0), BACKGROUND);
        let big = RgbImage::from_pixel(1920, 1080, BACKGROUND);
        let out = with_legend(&big, "000000.png", &comparison_legend(true));
        assert!(within_limits(out.width(), out.height()), "{out:?}");
    }

    #[test]
    fn sphere8_matches_the_reference_set() {
        let v = sphere8();
        assert_eq!(v.len(), 8);
        assert_eq!(v.iter().filter(|t| t.elevation_deg == 20.0).count(), 4);
        assert!(v
            .iter()
            .any(|t| t.elevation_deg == -30.0 && t.azimuth_deg == 315.0));
    }
}
