//! Baking a model's appearance from the video: the colours the keyframes show, gathered onto
//! the model's surface from its committed poses, as a per-triangle texture atlas
//! ([`agentstar_geom::atlas`]).
//!
//! Every texel of the atlas stands for one point of one triangle. For each frame the model is
//! rendered at its pose (the full renderer: depth and part ids), and each texel whose point is
//! the nearest surface at its pixel (same part, same depth), inside the frame's object mask
//! and outside its hand mask, takes the frame's colour there (bilinear), weighted by how
//! squarely the surface faces the camera (the cosine between its normal and the view ray;
//! grazing views under [`BakeConfig::min_cos`] are left out) and by its distance to the
//! mask's boundary (0 on the boundary pixel, rising to 1 at [`BakeConfig::boundary_px`]
//! inside: a mask's boundary is off by a pixel or two, and a pose's outline too). A texel's
//! colour is the weighted mean; texels no frame saw keep the model's own colour there and
//! count as unseen.
//!
//! Baked from wrong poses, the atlas locks the error in. So the frames are checked against
//! each other: each frame's colours are compared with every other frame's at the texels
//! both saw (after one gain per direction of the surface's normal, for exposure and
//! shading; the RMS over the tenth of those texels where they differ most, since a
//! misplaced print covers only part of the surface), a frame's
//! residual is the median over its partners weighted by the texels they share (one wrong
//! frame raises its own residual, not theirs), and a frame whose residual is
//! more than [`BakeConfig::disagree_ratio`] times the median frame's and over
//! [`BakeConfig::disagree_floor`] (8-bit units) disagrees — a frame in a twin of its true
//! pose carries the print to the wrong texels. Where the median frame itself is over the
//! floor, every frame over it disagrees (the poses do not agree at all). The caller refuses
//! to store a bake with disagreeing frames, naming them ([`Bake::disagreeing`]).
//!
//! No I/O: the caller reads the frames and stores the atlas.

use crate::update::GenPose;
use crate::TrackError;
use agentstar_geom::pose::Similarity;
use agentstar_geom::{with_atlas, AtlasLayout, ObjectModel, PinholeCamera, Texture};
use agentstar_render::scene::InstanceBuilder;
use agentstar_render::{render_full, BitMask, RenderBuffers};
use rayon::prelude::*;
use std::sync::Arc;

/// One keyframe to bake from: its camera, colour image (RGB, 8 bits, row-major, as
/// `image::RgbImage::as_raw`), object mask, hand mask and the model's pose in it.
#[derive(Debug, Clone, Copy)]
pub struct BakeFrame<'a> {
    pub name: &'a str,
    pub camera: &'a PinholeCamera,
    pub rgb: &'a [u8],
    pub mask: &'a BitMask,
    pub hand: Option<&'a BitMask>,
    pub pose: &'a GenPose,
}

/// How a bake samples and checks.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BakeConfig {
    /// Texels per model unit of length; `None`: the frames' median resolution on the object
    /// (pixels per model unit at the object's origin), so a texel is about a pixel where
    /// the model is typically seen — finer texels hold nothing the frames show, coarser
    /// ones blur the print.
    pub texels_per_unit: Option<f64>,
    /// Largest atlas side, texels: the density is lowered until the atlas fits
    /// (2048: 4 M texels, a 12 MB image in memory).
    pub max_atlas_side: u32,
    /// Distance from the mask's boundary (pixels) at which a pixel counts fully.
    pub boundary_px: f64,
    /// Least cosine between a surface's normal and the view ray for it to be sampled.
    pub min_cos: f64,
    /// Depth agreement for visibility, relative to the depth; plus 1% of the model's size.
    pub depth_tolerance: f64,
    /// A frame disagrees when its residual is over this (8-bit units, RMS over channels)…
    pub disagree_floor: f64,
    /// …and over this many times the median frame's.
    pub disagree_ratio: f64,
    /// Fewest texels a frame shares with the others for its residual to count.
    pub min_shared_texels: usize,
    /// The frames are compared at the scale of a pose's precision: each frame's colours
    /// averaged over a square of this share of the object's size in the frame (the square
    /// root of its mask's area) before the comparison, so that a print moved by the degree
    /// or two a tracked pose is off does not read as a print moved elsewhere (the atlas
    /// keeps the sharp colours).
    pub compare_blur: f64,
}

impl Default for BakeConfig {
    fn default() -> Self {
        BakeConfig {
            texels_per_unit: None,
            max_atlas_side: 2048,
            boundary_px: 3.0,
            min_cos: 0.15,
            depth_tolerance: 0.01,
            // A tenth of the 8-bit range. Where two right poses differ most (the tenth of
            // their shared texels on edges, noise, compression, shading a gain does not take
            // out) they differ by 6–12 on the synthetic printed mug; a print moved to the
            // wrong place differs by its contrast with what is there (45 on the mug turned
            // about its axis, 119 on a test box).
            disagree_floor: 24.0,
            // With three frames and one wrong, the good ones' residuals are about half the
            // wrong one's (the wrong one is half their reference); with more, less.
            disagree_ratio: 2.0,
            min_shared_texels: 64,
            // The printed mug with its handle high (`highmug`), ten keyframes the outline
            // settles: at the true poses the sharp comparison read 8–38 (38 at a frame that
            // sees the print at a slant), at tracked poses 0.5–6.4° off 9–59, every frame but
            // two over the floor; a print moved elsewhere differs over the whole badge.
            compare_blur: 0.02,
        }
    }
}

/// What one frame contributed and how well it agrees with the others.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameBake {
    pub name: String,
    /// Texels it saw.
    pub texels: usize,
    /// The most texels it shares with one other frame.
    pub shared_texels: usize,
    /// The frames it was compared with (sharing enough texels).
    pub partners: usize,
    /// The median over those frames (weighted by the texels shared) of the RMS difference of
    /// its colours from theirs over
    /// the tenth of the texels both saw where they differ most (8-bit units, after one gain
    /// for exposure); `None` without a partner.
    pub residual: Option<f64>,
    pub disagrees: bool,
}

/// A baked atlas and what the bake saw.
#[derive(Debug, Clone)]
pub struct Bake {
    pub layout: AtlasLayout,
    /// RGBA texels, row-major: colour, and alpha 255 where some frame saw the texel, 0
    /// where it keeps the model's own colour.
    pub rgba: Vec<u8>,
    /// Texels of the triangles' rectangles, and how many of them some frame saw.
    pub surface_texels: usize,
    pub seen_texels: usize,
    /// Texels seen by two frames or more, and the weighted mean of their weighted colour
    /// spread there (8-bit units, RMS over channels).
    pub multi_view_texels: usize,
    pub spread: Option<f64>,
    pub frames: Vec<FrameBake>,
    /// Every pair of frames compared (sharing enough texels).
    pub pairs: Vec<PairResidual>,
    /// The verdict's thresholds ([`BakeConfig::disagree_floor`], [`BakeConfig::disagree_ratio`]).
    pub disagree_floor: f64,
    pub disagree_ratio: f64,
}

impl Bake {
    pub fn seen_fraction(&self) -> f64 {
        if self.surface_texels == 0 {
            0.0
        } else {
            self.seen_texels as f64 / self.surface_texels as f64
        }
    }

    /// The frames that disagree, the worst first.
    pub fn disagreeing(&self) -> Vec<&FrameBake> {
        let mut d: Vec<&FrameBake> = self.frames.iter().filter(|f| f.disagrees).collect();
        d.sort_by(|a, b| {
            b.residual
                .unwrap_or(0.0)
                .total_cmp(&a.residual.unwrap_or(0.0))
        });
        d
    }

    /// The largest set of frames that agree (indices into [`Bake::frames`], in order): while
    /// some frame of the set disagrees with the rest, the one whose leaving makes the fewest
    /// of the others disagree (then the lowest median residual among them) leaves — not
    /// merely the worst: with three frames and one wrong, the wrong one and the right one
    /// beside it read alike (their pair is each one's nearest partner), and only the set
    /// each would leave tells them apart.
    pub fn agreeing(&self) -> Vec<usize> {
        agreeing_set(
            &self.pairs,
            self.frames.len(),
            self.disagree_floor,
            self.disagree_ratio,
        )
    }

    /// The atlas as a texture (its RGB).
    pub fn texture(&self, source: &str) -> Result<Texture, TrackError> {
        let rgb = self
            .rgba
            .chunks_exact(4)
            .flat_map(|c| [c[0], c[1], c[2]])
            .collect();
        Texture::new(source, self.layout.width, self.layout.height, rgb)
            .map_err(|e| TrackError::Invalid(e.to_string()))
    }

    /// `model` (the one baked) coloured by the atlas.
    pub fn apply(&self, model: &ObjectModel) -> Result<ObjectModel, TrackError> {
        with_atlas(model, &self.layout, Arc::new(self.texture("baked atlas")?))
            .map_err(|e| TrackError::Invalid(e.to_string()))
    }
}

/// Pixels per model unit at the object's origin, the median over the frames.
fn frames_resolution(scale: f64, frames: &[BakeFrame<'_>]) -> Option<f64> {
    let mut v: Vec<f64> = frames
        .iter()
        .filter_map(|f| {
            let z = f.pose.pose.translation.z;
            let r = 0.5 * (f.camera.fx + f.camera.fy) * scale / z;
            (r.is_finite() && r > 0.0).then_some(r)
        })
        .collect();
    if v.is_empty() {
        return None;
    }
    v.sort_by(f64::total_cmp);
    Some(v[v.len() / 2])
}

/// The layout at the density asked for, lowered until the atlas fits `max_side`.
fn fit_layout(
    model: &ObjectModel,
    texels_per_unit: f64,
    max_side: u32,
) -> Result<AtlasLayout, TrackError> {
    // In 1/1024ths of a texel per unit: a binary fraction with a short decimal form, which
    // the bake file's JSON carries exactly, so the loader lays out the same atlas.
    let quantise = |d: f64| ((d * 1024.0).floor() / 1024.0).max(1.0 / 1024.0);
    let mut d = quantise(texels_per_unit);
    for _ in 0..80 {
        // An atlas about square: the width from the rectangles' total area.
        let area: f64 = model
            .parts
            .iter()
            .flat_map(|p| (0..p.mesh.triangles.len()).map(move |t| p.mesh.triangle(t)))
            .map(|[a, b, c]| {
                let l = (b - a).norm().max((c - b).norm()).max((a - c).norm());
                let h = if l > 0.0 {
                    (b - a).cross(&(c - a)).norm() / l
                } else {
                    0.0
                };
                ((l * d).ceil().max(1.0) + 2.0) * ((h * d).ceil().max(1.0) + 2.0)
            })
            .sum();
        let side = (area * 1.2).sqrt().ceil().max(16.0);
        let width = (side as u32).next_power_of_two().min(max_side);
        if let Ok(layout) = AtlasLayout::new(model, d, width) {
            if layout.height <= max_side {
                return Ok(layout);
            }
        }
        d = quantise(d * 0.85);
    }
    Err(TrackError::Invalid(format!(
        "the model's {} triangles do not fit an atlas of {max_side}×{max_side} texels",
        model.triangle_count()
    )))
}

/// A part's triangle placed in one frame's camera.
struct PlacedTriangle {
    corners: [[f64; 3]; 3],
    normal: [f64; 3],
}

/// Each pixel's distance (in pixels, chamfer 3-4 / 3) to the nearest pixel outside
/// `usable`, capped at `cap`.
fn inside_distance(usable: &BitMask, cap: f64) -> Vec<f32> {
    let (w, h) = (usable.width() as usize, usable.height() as usize);
    let big = (3.0 * (cap + 2.0)) as u32;
    let mut d: Vec<u32> = (0..w * h)
        .map(|k| {
            if usable.get((k % w) as u32, (k / w) as u32) {
                big
            } else {
                0
            }
        })
        .collect();
    let at = |d: &Vec<u32>, x: isize, y: isize| -> u32 {
        if x < 0 || y < 0 || x >= w as isize || y >= h as isize {
            0
        } else {
            d[y as usize * w + x as usize]
        }
    };
    for y in 0..h as isize {
        for x in 0..w as isize {
            let k = y as usize * w + x as usize;
            if d[k] == 0 {
                continue;
            }
            let m = [
                at(&d, x - 1, y) + 3,
                at(&d, x, y - 1) + 3,
                at(&d, x - 1, y - 1) + 4,
                at(&d, x + 1, y - 1) + 4,
            ]
            .into_iter()
            .min()
            .unwrap_or(big);
            d[k] = d[k].min(m);
        }
    }
    for y in (0..h as isize).rev() {
        for x in (0..w as isize).rev() {
            let k = y as usize * w + x as usize;
            if d[k] == 0 {
                continue;
            }
            let m = [
                at(&d, x + 1, y) + 3,
                at(&d, x, y + 1) + 3,
                at(&d, x + 1, y + 1) + 4,
                at(&d, x - 1, y + 1) + 4,
            ]
            .into_iter()
            .min()
            .unwrap_or(big);
            d[k] = d[k].min(m);
        }
    }
    d.into_iter().map(|v| v as f32 / 3.0).collect()
}

/// Each pixel's mean colour over the pixels of `usable` in the square of half-side `radius`
/// around it (integral images); pixels with none of `usable` in reach keep their own. Empty
/// for a radius of 0 (the sharp colours are compared).
fn masked_box_mean(rgb: &[u8], usable: &BitMask, radius: u32) -> Vec<[f32; 3]> {
    if radius == 0 {
        return Vec::new();
    }
    let (w, h) = (usable.width() as usize, usable.height() as usize);
    // Sums over [0, x) × [0, y), (w + 1) × (h + 1): three channels and the count.
    let stride = w + 1;
    let mut sums = vec![[0.0f64; 4]; stride * (h + 1)];
    for y in 0..h {
        let mut row = [0.0f64; 4];
        for x in 0..w {
            if usable.get(x as u32, y as u32) {
                let k = 3 * (y * w + x);
                for c in 0..3 {
                    row[c] += f64::from(rgb[k + c]);
                }
                row[3] += 1.0;
            }
            let above = sums[y * stride + x + 1];
            sums[(y + 1) * stride + x + 1] = [0, 1, 2, 3].map(|c| above[c] + row[c]);
        }
    }
    let r = radius as usize;
    (0..w * h)
        .map(|k| {
            let (x, y) = (k % w, k / w);
            let (x0, x1) = (x.saturating_sub(r), (x + r + 1).min(w));
            let (y0, y1) = (y.saturating_sub(r), (y + r + 1).min(h));
            let at = |xx: usize, yy: usize| sums[yy * stride + xx];
            let (a, b, c, d) = (at(x0, y0), at(x1, y0), at(x0, y1), at(x1, y1));
            let s = [0, 1, 2, 3].map(|i| d[i] - b[i] - c[i] + a[i]);
            if s[3] > 0.5 {
                [0, 1, 2].map(|i| (s[i] / s[3]) as f32)
            } else {
                let p = 3 * k;
                [0, 1, 2].map(|i| f32::from(rgb[p + i]))
            }
        })
        .collect()
}

/// What one frame sees of the atlas: for each texel it saw, its index, weight and colour.
struct FrameView<'f> {
    frame: BakeFrame<'f>,
    buffers: RenderBuffers,
    distance: Vec<f32>,
    /// The frame's colours averaged over the usable mask in a square around each pixel
    /// ([`BakeConfig::compare_blur`]): what the frames are compared by. Empty: the sharp
    /// colours.
    smoothed: Vec<[f32; 3]>,
    usable: BitMask,
    placed: Vec<Vec<PlacedTriangle>>,
}

impl<'f> FrameView<'f> {
    fn new(model: &ObjectModel, scale: f64, frame: BakeFrame<'f>) -> Self {
        let cam = frame.pose.pose.with_scale(scale);
        let mut instances = Vec::new();
        InstanceBuilder::default().build(model, &frame.pose.states, &cam, &mut instances);
        let buffers = render_full(frame.camera, &instances);
        let usable = match frame.hand {
            Some(hand) => frame.mask.and_not(hand),
            None => frame.mask.clone(),
        };
        let transforms = model.tree.part_transforms(&frame.pose.states);
        let placed = model
            .parts
            .iter()
            .zip(&transforms)
            .map(|(part, t)| {
                let camera_from_part = cam.compose(&Similarity::from_rigid(t));
                part.mesh
                    .triangles
                    .iter()
                    .map(|tri| {
                        let c = tri.map(|i| {
                            let p =
                                camera_from_part.transform_point(&part.mesh.positions[i as usize]);
                            [p.x, p.y, p.z]
                        });
                        let e1 = [0, 1, 2].map(|i| c[1][i] - c[0][i]);
                        let e2 = [0, 1, 2].map(|i| c[2][i] - c[0][i]);
                        let n = [
                            e1[1] * e2[2] - e1[2] * e2[1],
                            e1[2] * e2[0] - e1[0] * e2[2],
                            e1[0] * e2[1] - e1[1] * e2[0],
                        ];
                        let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                        let normal = if len > 0.0 {
                            n.map(|v| v / len)
                        } else {
                            [0.0; 3]
                        };
                        PlacedTriangle { corners: c, normal }
                    })
                    .collect()
            })
            .collect();
        FrameView {
            frame,
            distance: Vec::new(),
            smoothed: Vec::new(),
            buffers,
            usable,
            placed,
        }
    }

    fn valid(frame: &BakeFrame<'_>) -> bool {
        let (w, h) = (frame.camera.width, frame.camera.height);
        frame.rgb.len() == 3 * w as usize * h as usize
            && (frame.mask.width(), frame.mask.height()) == (w, h)
            && frame.hand.is_none_or(|m| (m.width(), m.height()) == (w, h))
    }

    fn colour(&self, u: f64, v: f64) -> [f64; 3] {
        let (w, h) = (
            self.frame.camera.width as i64,
            self.frame.camera.height as i64,
        );
        let (x, y) = (u - 0.5, v - 0.5);
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let px = |xi: i64, yi: i64| -> [f64; 3] {
            let (xi, yi) = (xi.clamp(0, w - 1), yi.clamp(0, h - 1));
            let k = 3 * (yi * w + xi) as usize;
            [0, 1, 2].map(|c| f64::from(self.frame.rgb[k + c]))
        };
        let (x0, y0) = (x0 as i64, y0 as i64);
        let (a, b, c, d) = (
            px(x0, y0),
            px(x0 + 1, y0),
            px(x0, y0 + 1),
            px(x0 + 1, y0 + 1),
        );
        [0, 1, 2].map(|i| {
            let top = a[i] + (b[i] - a[i]) * fx;
            let bottom = c[i] + (d[i] - c[i]) * fx;
            top + (bottom - top) * fy
        })
    }

    /// The colour the frames are compared by at pixel `k` (see [`FrameView::smoothed`]).
    fn compared(&self, k: usize, sharp: [f64; 3]) -> [f64; 3] {
        match self.smoothed.get(k) {
            Some(c) => c.map(f64::from),
            None => sharp,
        }
    }

    /// Calls `f(texel, weight, colour, compared colour)` for every texel this frame sees.
    fn for_each_sample(
        &self,
        layout: &AtlasLayout,
        cfg: &BakeConfig,
        depth_floor: f64,
        mut f: impl FnMut(usize, f64, [f64; 3], [f64; 3]),
    ) {
        let cam = self.frame.camera;
        let (w, h) = (cam.width, cam.height);
        for (p, patches) in layout.patches.iter().enumerate() {
            for (t, patch) in patches.iter().enumerate() {
                let tri = &self.placed[p][t];
                let c = tri.corners;
                for y in patch.y0..patch.y0 + patch.height {
                    for x in patch.x0..patch.x0 + patch.width {
                        let b = patch.texel_barycentric(x, y);
                        let q = [0, 1, 2].map(|i| b[0] * c[0][i] + b[1] * c[1][i] + b[2] * c[2][i]);
                        if q[2] <= 0.0 {
                            continue;
                        }
                        let dist = (q[0] * q[0] + q[1] * q[1] + q[2] * q[2]).sqrt();
                        let cos =
                            -(tri.normal[0] * q[0] + tri.normal[1] * q[1] + tri.normal[2] * q[2])
                                / dist;
                        // Open meshes show both sides; a closed one's back faces are hidden
                        // and fail the depth test below.
                        let cos = cos.abs();
                        if cos < cfg.min_cos {
                            continue;
                        }
                        let u = cam.fx * q[0] / q[2] + cam.cx;
                        let v = cam.fy * q[1] / q[2] + cam.cy;
                        if !(u >= 0.0 && v >= 0.0 && u < f64::from(w) && v < f64::from(h)) {
                            continue;
                        }
                        let (px, py) = (u as u32, v as u32);
                        let k = (py * w + px) as usize;
                        if usize::from(self.buffers.part[k]) != p {
                            continue;
                        }
                        let z = f64::from(self.buffers.depth[k]);
                        if (z - q[2]).abs() > cfg.depth_tolerance * q[2] + depth_floor {
                            continue;
                        }
                        if !self.usable.get(px, py) {
                            continue;
                        }
                        let inside = f64::from(self.distance[k]);
                        let edge = ((inside - 1.0) / cfg.boundary_px).clamp(0.0, 1.0);
                        let weight = cos * edge;
                        if weight <= 0.0 {
                            continue;
                        }
                        let sharp = self.colour(u, v);
                        f(
                            (y * layout.width + x) as usize,
                            weight,
                            sharp,
                            self.compared(k, sharp),
                        );
                    }
                }
            }
        }
    }
}

/// Share of the shared texels a pair's residual is taken over: those where the two frames
/// differ most. A print moved to the wrong place covers only part of the surface (a badge
/// on a mug), and over all shared texels its difference drowns in the plain ones.
const DISAGREE_SHARE: f64 = 0.1;

/// Directions a surface's normal is binned into for the gains between two frames: each
/// face of a cube in 4 × 4 cells.
const NORMAL_BINS: usize = 96;

/// Each texel's bin of its triangle's normal (part frame), for [`pair_residual`].
fn normal_bins(model: &ObjectModel, layout: &AtlasLayout) -> Vec<u8> {
    let mut bins = vec![0u8; layout.texel_count()];
    for (p, patches) in layout.patches.iter().enumerate() {
        let mesh = &model.parts[p].mesh;
        for (t, patch) in patches.iter().enumerate() {
            let [a, b, c] = mesh.triangle(t);
            let n = (b - a).cross(&(c - a));
            let len = n.norm();
            let n = if len > 0.0 { n / len } else { n };
            let k = (0..3)
                .max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))
                .unwrap_or(2);
            let face = 2 * k + usize::from(n[k] < 0.0);
            let (u, v) = (n[(k + 1) % 3], n[(k + 2) % 3]);
            let cell = |x: f64| (((x + 1.0) * 2.0).floor() as usize).min(3);
            let bin = (face * 16 + cell(u) * 4 + cell(v)) as u8;
            for y in patch.y0..patch.y0 + patch.height {
                let row = (y * layout.width) as usize;
                bins[row + patch.x0 as usize..row + (patch.x0 + patch.width) as usize].fill(bin);
            }
        }
    }
    bins
}

/// How far two frames' colours (8-bit units) differ at the texels both saw (`a`, `b`
/// sorted by texel): after one least-squares gain from `a` to `b` per direction of the
/// surface's normal ([`normal_bins`]: exposure, and the shading a light puts on each side,
/// which a print moved elsewhere cannot imitate), the weighted RMS over channels of the
/// [`DISAGREE_SHARE`] of shared texels where they differ most; and how many texels they
/// share.
fn pair_residual(
    a: &[(u32, f32, [f32; 3])],
    b: &[(u32, f32, [f32; 3])],
    bins: &[u8],
) -> (usize, Option<f64>) {
    let (mut i, mut j) = (0, 0);
    let mut pairs: Vec<(f64, [f64; 3], [f64; 3], usize)> = Vec::new();
    let mut sums = [(0.0f64, 0.0f64); NORMAL_BINS];
    while i < a.len() && j < b.len() {
        match a[i].0.cmp(&b[j].0) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                let w = f64::from(a[i].1.min(b[j].1));
                let x = a[i].2.map(f64::from);
                let y = b[j].2.map(f64::from);
                let bin = usize::from(bins.get(a[i].0 as usize).copied().unwrap_or(0));
                for c in 0..3 {
                    sums[bin].0 += w * x[c] * y[c];
                    sums[bin].1 += w * x[c] * x[c];
                }
                pairs.push((w, x, y, bin));
                i += 1;
                j += 1;
            }
        }
    }
    let n = pairs.len();
    if n == 0 {
        return (n, None);
    }
    let mut d: Vec<(f64, f64)> = pairs
        .iter()
        .map(|(w, x, y, bin)| {
            let (sab, saa) = sums[*bin];
            let gain = if saa > 0.0 { sab / saa } else { 1.0 };
            let d2 = (0..3).map(|c| (y[c] - gain * x[c]).powi(2)).sum::<f64>() / 3.0;
            (d2, *w)
        })
        .collect();
    d.sort_by(|p, q| q.0.total_cmp(&p.0));
    let top = ((n as f64 * DISAGREE_SHARE).ceil() as usize).clamp(1, n);
    let (mut sd, mut sw) = (0.0, 0.0);
    for &(d2, w) in &d[..top] {
        sd += w * d2;
        sw += w;
    }
    if sw <= 0.0 {
        return (n, None);
    }
    (n, Some((sd / sw).sqrt()))
}

/// One frame's samples: (texel, weight, colour) for every texel it saw, in texel order
/// once sorted.
type Samples = Vec<(u32, f32, [f32; 3])>;

/// Per texel running sums.
#[derive(Debug, Clone, Copy, Default)]
struct Texel {
    weight: f64,
    sum: [f64; 3],
    sum_sq: [f64; 3],
    frames: u16,
}

/// Bakes `model`'s colours from `frames` (poses in internal units, `scale` the pose file's).
/// Errors: no frames, a frame whose image or masks are not its camera's size, a pose that
/// is not finite, a model that does not fit an atlas.
pub fn bake(
    model: &ObjectModel,
    scale: f64,
    frames: &[BakeFrame<'_>],
    cfg: &BakeConfig,
) -> Result<Bake, TrackError> {
    if frames.is_empty() {
        return Err(TrackError::Invalid("no frames to bake from".into()));
    }
    if !(scale.is_finite() && scale > 0.0) {
        return Err(TrackError::Invalid(format!(
            "the scale must be a positive number, not {scale}"
        )));
    }
    for f in frames {
        if !FrameView::valid(f) {
            return Err(TrackError::Invalid(format!(
                "frame {}: its image or masks are not its camera's {}×{}",
                f.name, f.camera.width, f.camera.height
            )));
        }
        let p = &f.pose.pose;
        let finite = p.translation.iter().all(|v| v.is_finite())
            && p.rotation.coords.iter().all(|v| v.is_finite())
            && f.pose.states.iter().all(|v| v.is_finite());
        if !finite || p.translation.z <= 0.0 {
            return Err(TrackError::Invalid(format!(
                "frame {}: its pose is not finite or not in front of the camera",
                f.name
            )));
        }
    }
    let density = match cfg.texels_per_unit {
        Some(d) => d,
        None => frames_resolution(scale, frames).ok_or_else(|| {
            TrackError::Invalid("the frames give no resolution on the object".into())
        })?,
    };
    let layout = fit_layout(model, density, cfg.max_atlas_side.max(16))?;
    let diagonal = model
        .parts
        .iter()
        .map(|p| (p.bounds.max - p.bounds.min).norm())
        .fold(0.0, f64::max);
    let depth_floor = 0.01 * diagonal * scale;

    // Pass 1: the weighted sums per texel (frames in parallel, summed in frame order), and
    // each frame's colours as compared (smoothed) for pass 2.
    let (colours, samples): (Vec<Samples>, Vec<Samples>) = frames
        .par_iter()
        .map(|f| {
            let mut v = FrameView::new(model, scale, *f);
            v.distance = inside_distance(&v.usable, cfg.boundary_px);
            let radius = cfg.compare_blur * (v.usable.count() as f64).sqrt();
            v.smoothed = masked_box_mean(f.rgb, &v.usable, radius.round() as u32);
            let (mut sharp, mut compared) = (Vec::new(), Vec::new());
            v.for_each_sample(&layout, cfg, depth_floor, |k, w, c, m| {
                sharp.push((k as u32, w as f32, c.map(|x| x as f32)));
                compared.push((k as u32, w as f32, m.map(|x| x as f32)));
            });
            (sharp, compared)
        })
        .unzip();
    let mut texels = vec![Texel::default(); layout.texel_count()];
    let mut seen_by_frame = Vec::with_capacity(frames.len());
    for s in &colours {
        seen_by_frame.push(s.len());
        for &(k, w, c) in s {
            let t = &mut texels[k as usize];
            let w = f64::from(w);
            t.weight += w;
            for (i, &ci) in c.iter().enumerate() {
                let ci = f64::from(ci);
                t.sum[i] += w * ci;
                t.sum_sq[i] += w * ci * ci;
            }
            t.frames = t.frames.saturating_add(1);
        }
    }
    // Pass 2: each frame against each other frame at the texels both saw; a frame's
    // residual is the median over its partners weighted by the texels shared, so one wrong
    // frame raises its own residual, not its partners'.
    let mut samples = samples;
    samples.par_iter_mut().for_each(|s| s.sort_by_key(|x| x.0));
    let texel_bins = normal_bins(model, &layout);
    let partners_of = |i: usize| -> Vec<usize> {
        // Every other frame up to 24 frames; beyond, the 24 nearest in the sequence.
        let n = frames.len();
        let reach = 12usize;
        if n <= 2 * reach + 1 {
            (0..n).filter(|&j| j != i).collect()
        } else {
            let lo = i.saturating_sub(reach).min(n - 2 * reach - 1);
            (lo..lo + 2 * reach + 1).filter(|&j| j != i).collect()
        }
    };
    // Each pair once (i < j), in parallel over i.
    let pair_rows: Vec<(usize, Vec<PairResidual>)> = (0..frames.len())
        .into_par_iter()
        .map(|i| {
            let mut shared_most = 0usize;
            let mut row = Vec::new();
            for j in partners_of(i) {
                let (n, r) = pair_residual(&samples[i], &samples[j], &texel_bins);
                shared_most = shared_most.max(n);
                if let (true, Some(r), true) = (n >= cfg.min_shared_texels, r, i < j) {
                    row.push(PairResidual {
                        a: i,
                        b: j,
                        shared: n,
                        residual: r,
                    });
                }
            }
            (shared_most, row)
        })
        .collect();
    drop(samples);
    let pairs: Vec<PairResidual> = pair_rows.iter().flat_map(|r| r.1.clone()).collect();
    let every = vec![true; frames.len()];
    let verdicts = frame_verdicts(&pairs, &every, cfg.disagree_floor, cfg.disagree_ratio);
    let frame_reports: Vec<FrameBake> = frames
        .iter()
        .zip(&pair_rows)
        .zip(&seen_by_frame)
        .zip(verdicts)
        .map(|(((f, (shared, _)), &seen), v)| FrameBake {
            name: f.name.to_string(),
            texels: seen,
            shared_texels: *shared,
            partners: v.partners,
            residual: v.residual,
            disagrees: v.disagrees,
        })
        .collect();

    // The atlas: seen texels their mean, the rest the model's own colour.
    let mut rgba = vec![0u8; 4 * layout.texel_count()];
    let (mut surface_texels, mut seen_texels, mut multi) = (0usize, 0usize, 0usize);
    let (mut spread_sum, mut spread_weight) = (0.0, 0.0);
    let to_byte = |v: f64| v.round().clamp(0.0, 255.0) as u8;
    for (p, patches) in layout.patches.iter().enumerate() {
        let part = &model.parts[p];
        for (t, patch) in patches.iter().enumerate() {
            for y in patch.y0..patch.y0 + patch.height {
                for x in patch.x0..patch.x0 + patch.width {
                    let k = (y * layout.width + x) as usize;
                    surface_texels += 1;
                    let tx = &texels[k];
                    let out = &mut rgba[4 * k..4 * k + 4];
                    if tx.weight > 0.0 {
                        seen_texels += 1;
                        let mean = tx.sum.map(|s| s / tx.weight);
                        for i in 0..3 {
                            out[i] = to_byte(mean[i]);
                        }
                        out[3] = 255;
                        if tx.frames >= 2 {
                            multi += 1;
                            let var: f64 = (0..3)
                                .map(|i| (tx.sum_sq[i] / tx.weight - mean[i] * mean[i]).max(0.0))
                                .sum::<f64>()
                                / 3.0;
                            spread_sum += tx.weight * var.sqrt();
                            spread_weight += tx.weight;
                        }
                    } else {
                        let own = match &part.surface {
                            Some(s) => {
                                let b = patch.texel_barycentric(x, y);
                                s.color_at(t, [b[0] as f32, b[1] as f32, b[2] as f32])
                            }
                            None => part.color,
                        };
                        for i in 0..3 {
                            out[i] = to_byte(f64::from(own[i]) * 255.0);
                        }
                        out[3] = 0;
                    }
                }
            }
        }
    }
    Ok(Bake {
        layout,
        rgba,
        surface_texels,
        seen_texels,
        multi_view_texels: multi,
        spread: (spread_weight > 0.0).then(|| spread_sum / spread_weight),
        frames: frame_reports,
        pairs,
        disagree_floor: cfg.disagree_floor,
        disagree_ratio: cfg.disagree_ratio,
    })
}

/// One frame's verdict among a set of frames ([`frame_verdicts`]).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Verdict {
    partners: usize,
    residual: Option<f64>,
    disagrees: bool,
}

/// Each frame's residual and verdict among the frames `within` marks (the others get
/// none): the median of its pairs' residuals with those frames, weighted by the texels
/// shared (a partner that saw little of what it saw — a grazing side, a rim — says
/// little), and whether it is over `floor` ([`BakeConfig::disagree_floor`]) and over
/// `ratio` ([`BakeConfig::disagree_ratio`]) times the median frame's (or the median frame
/// is over the floor too: the poses do not agree at all).
fn frame_verdicts(pairs: &[PairResidual], within: &[bool], floor: f64, ratio: f64) -> Vec<Verdict> {
    let mut per_frame: Vec<Vec<(f64, usize)>> = vec![Vec::new(); within.len()];
    for p in pairs {
        if within[p.a] && within[p.b] {
            per_frame[p.a].push((p.residual, p.shared));
            per_frame[p.b].push((p.residual, p.shared));
        }
    }
    let medians: Vec<Option<f64>> = per_frame
        .iter_mut()
        .map(|rs| {
            rs.sort_by(|a, b| a.0.total_cmp(&b.0));
            let half = rs.iter().map(|r| r.1).sum::<usize>().div_ceil(2);
            let mut seen = 0usize;
            rs.iter().find_map(|&(r, n)| {
                seen += n;
                (seen >= half).then_some(r)
            })
        })
        .collect();
    let mut sorted: Vec<f64> = medians.iter().flatten().copied().collect();
    sorted.sort_by(f64::total_cmp);
    let median = (!sorted.is_empty()).then(|| sorted[(sorted.len() - 1) / 2]);
    per_frame
        .iter()
        .zip(medians)
        .map(|(rs, residual)| Verdict {
            partners: rs.len(),
            residual,
            disagrees: match (residual, median) {
                (Some(r), Some(m)) => r > floor && (r > ratio * m || m > floor),
                _ => false,
            },
        })
        .collect()
}

/// [`Bake::agreeing`] over `n` frames compared in `pairs`.
fn agreeing_set(pairs: &[PairResidual], n: usize, floor: f64, ratio: f64) -> Vec<usize> {
    let mut within = vec![true; n];
    loop {
        let verdicts = frame_verdicts(pairs, &within, floor, ratio);
        let disagreeing: Vec<usize> = (0..n)
            .filter(|&i| within[i] && verdicts[i].disagrees)
            .collect();
        // Each candidate's leaving: how many of the rest still disagree, and the median
        // residual of the rest.
        let cost = |leaving: usize| {
            let mut rest = within.clone();
            rest[leaving] = false;
            let v = frame_verdicts(pairs, &rest, floor, ratio);
            let still = (0..n).filter(|&i| rest[i] && v[i].disagrees).count();
            let mut rs: Vec<f64> = (0..n)
                .filter(|&i| rest[i])
                .filter_map(|i| v[i].residual)
                .collect();
            rs.sort_by(f64::total_cmp);
            let median = rs
                .get(rs.len().saturating_sub(1) / 2)
                .copied()
                .unwrap_or(0.0);
            (still, median)
        };
        let leaving = disagreeing
            .iter()
            .map(|&i| (i, cost(i)))
            .min_by(|a, b| a.1 .0.cmp(&b.1 .0).then(a.1 .1.total_cmp(&b.1 .1)))
            .map(|(i, _)| i);
        match leaving {
            Some(i) => within[i] = false,
            None => break,
        }
    }
    (0..n).filter(|&i| within[i]).collect()
}

/// Two frames' comparison ([`pair_residual`]) where they share enough texels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairResidual {
    /// The frames (indices into [`Bake::frames`], `a < b`).
    pub a: usize,
    pub b: usize,
    /// Texels both saw.
    pub shared: usize,
    /// 8-bit units (see [`FrameBake::residual`]).
    pub residual: f64,
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::pose::ObjectPose;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{KinematicTree, Part, SurfaceAppearance, UnitQuaternion, Vector3};
    use agentstar_render::surface::surface_colors;
    use agentstar_render::PosedModel;

    /// A box whose colour runs with position: red along x, green along y, blue along z, so
    /// no half-turn leaves it looking the same, though its outline stays.
    fn printed_box() -> (ObjectModel, ObjectModel) {
        let (sx, sy, sz) = (1.0, 0.6, 0.4);
        let mesh = cuboid(sx, sy, sz).expect("box");
        let corner_color = mesh
            .triangles
            .iter()
            .map(|t| {
                t.map(|i| {
                    let p = mesh.positions[i as usize];
                    [
                        (0.15 + 0.7 * (p.x / sx + 0.5)) as f32,
                        (0.15 + 0.7 * (p.y / sy + 0.5)) as f32,
                        (0.15 + 0.7 * (p.z / sz + 0.5)) as f32,
                    ]
                })
            })
            .collect();
        let surface = SurfaceAppearance::vertex_colored(corner_color).expect("colours");
        let printed = ObjectModel {
            parts: vec![Part::new("body", mesh.clone(), [0.5; 3])
                .with_surface(Arc::new(surface))
                .expect("surface")],
            tree: KinematicTree::rigid(1),
        };
        let plain = ObjectModel {
            parts: vec![Part::new("body", mesh, [0.5; 3])],
            tree: KinematicTree::rigid(1),
        };
        (printed, plain)
    }

    struct Shot {
        name: String,
        camera: PinholeCamera,
        rgb: Vec<u8>,
        mask: BitMask,
        pose: GenPose,
    }

    /// The printed box seen from eight directions round and over it.
    fn shots(model: &ObjectModel) -> Vec<Shot> {
        let camera = PinholeCamera::new(300.0, 300.0, 80.0, 80.0, 160, 160).expect("camera");
        (0..8)
            .map(|i| {
                let a = i as f64 * std::f64::consts::TAU / 8.0;
                let rotation =
                    UnitQuaternion::from_euler_angles(0.5 + 0.3 * (i % 2) as f64, a, 0.2 * a);
                let pose = GenPose::new(
                    ObjectPose::new(rotation, Vector3::new(0.0, 0.0, 3.0)),
                    vec![],
                );
                let posed = PosedModel::new(model, &[], &pose.pose.with_scale(1.0));
                let buffers = agentstar_render::render_full(&camera, &posed.instances);
                let colours = surface_colors(model, &posed.instances, &camera, &buffers);
                let rgb = colours
                    .iter()
                    .flat_map(|c| c.unwrap_or([0.0; 3]).map(|v| (v * 255.0).round() as u8))
                    .collect();
                Shot {
                    name: format!("{i:06}"),
                    camera,
                    rgb,
                    mask: buffers.silhouette(),
                    pose,
                }
            })
            .collect()
    }

    fn frames(shots: &[Shot]) -> Vec<BakeFrame<'_>> {
        shots
            .iter()
            .map(|s| BakeFrame {
                name: &s.name,
                camera: &s.camera,
                rgb: &s.rgb,
                mask: &s.mask,
                hand: None,
                pose: &s.pose,
            })
            .collect()
    }

    #[test]
    fn baking_from_true_poses_reproduces_the_print() {
        let (printed, plain) = shots_model();
        let shots = shots(&printed);
        let b = bake(&plain, 1.0, &frames(&shots), &BakeConfig::default()).expect("bake");
        assert!(b.seen_fraction() > 0.75, "seen {}", b.seen_fraction());
        assert!(b.disagreeing().is_empty(), "{:?}", b.frames);
        // Every seen texel within a few 8-bit units of the print at its point.
        let truth = printed.parts[0].surface.as_ref().expect("print");
        let mut errors = Vec::new();
        for (t, patch) in b.layout.patches[0].iter().enumerate() {
            for y in patch.y0..patch.y0 + patch.height {
                for x in patch.x0..patch.x0 + patch.width {
                    let k = (y * b.layout.width + x) as usize;
                    if b.rgba[4 * k + 3] == 0 {
                        continue;
                    }
                    let bary = patch.texel_barycentric(x, y).map(|v| v as f32);
                    let want = truth.color_at(t, bary);
                    for (i, &w) in want.iter().enumerate() {
                        let e = (f64::from(b.rgba[4 * k + i]) - f64::from(w) * 255.0).abs();
                        errors.push(e);
                    }
                }
            }
        }
        errors.sort_by(f64::total_cmp);
        let mean = errors.iter().sum::<f64>() / errors.len() as f64;
        let p99 = errors[errors.len() * 99 / 100];
        // Texels on an edge seen only next to the outline read a pixel across it.
        assert!(
            mean < 2.0 && p99 < 10.0,
            "mean {mean:.2}, 99th percentile {p99:.1}"
        );
        // The baked model draws the print: its mean colour is the printed one's.
        let baked = b.apply(&plain).expect("apply");
        let (m0, m1) = (baked.parts[0].color, printed.parts[0].color);
        assert!(
            (0..3).all(|i| (m0[i] - m1[i]).abs() < 0.03),
            "{m0:?} vs {m1:?}"
        );
    }

    fn shots_model() -> (ObjectModel, ObjectModel) {
        printed_box()
    }

    #[test]
    fn a_frame_in_a_twin_of_its_pose_is_named() {
        let (printed, plain) = printed_box();
        let mut shots = shots(&printed);
        // Frame 3 put in its twin: a half-turn about the box's own z axis, same outline.
        let twin = shots[3].pose.pose.rotation
            * UnitQuaternion::from_euler_angles(0.0, 0.0, std::f64::consts::PI);
        shots[3].pose.pose = ObjectPose::new(twin, shots[3].pose.pose.translation);
        let b = bake(&plain, 1.0, &frames(&shots), &BakeConfig::default()).expect("bake");
        let named: Vec<&str> = b.disagreeing().iter().map(|f| f.name.as_str()).collect();
        assert_eq!(named, ["000003"], "{:?}", b.frames);
        // Without it, the rest agree.
        let rest: Vec<BakeFrame> = frames(&shots)
            .into_iter()
            .filter(|f| f.name != "000003")
            .collect();
        let b = bake(&plain, 1.0, &rest, &BakeConfig::default()).expect("bake");
        assert!(b.disagreeing().is_empty(), "{:?}", b.frames);
    }

    #[test]
    fn bad_frames_are_refused_with_their_name() {
        let (printed, plain) = printed_box();
        let mut shots = shots(&printed);
        shots[2].rgb.truncate(10);
        let e =
            bake(&plain, 1.0, &frames(&shots), &BakeConfig::default()).expect_err("short image");
        assert!(e.to_string().contains("000002"), "{e}");
        let e = bake(&plain, 1.0, &[], &BakeConfig::default()).expect_err("no frames");
        assert!(e.to_string().contains("no frames"), "{e}");
    }

    #[test]
    fn the_frame_that_leaves_is_the_one_whose_leaving_makes_the_rest_agree() {
        let pair = |a, b, shared, residual| PairResidual {
            a,
            b,
            shared,
            residual,
        };
        // Frame 2 is wrong; frame 0 shares most with it, so 0 and 2 read alike (40).
        let pairs = [
            pair(0, 1, 100, 8.0),
            pair(0, 2, 300, 40.0),
            pair(1, 2, 100, 40.0),
        ];
        let v = frame_verdicts(&pairs, &[true; 3], 24.0, 2.0);
        assert_eq!(v[0].residual, Some(40.0));
        assert_eq!(v[2].residual, Some(40.0));
        assert!(v[0].disagrees && v[2].disagrees);
        assert_eq!(agreeing_set(&pairs, 3, 24.0, 2.0), vec![0, 1]);
        // Nothing agrees: every frame leaves but one.
        let apart = [
            pair(0, 1, 100, 50.0),
            pair(0, 2, 100, 60.0),
            pair(1, 2, 100, 70.0),
        ];
        assert!(agreeing_set(&apart, 3, 24.0, 2.0).len() <= 1);
        // Frames that agree stay.
        let close = [
            pair(0, 1, 100, 9.0),
            pair(0, 2, 100, 12.0),
            pair(1, 2, 100, 10.0),
        ];
        assert_eq!(agreeing_set(&close, 3, 24.0, 2.0), vec![0, 1, 2]);
    }

    #[test]
    fn inside_distance_counts_pixels_from_the_boundary() {
        let m = BitMask::from_fn(9, 9, |x, y| (1..8).contains(&x) && (1..8).contains(&y));
        let d = inside_distance(&m, 5.0);
        assert_eq!(d[0], 0.0);
        assert_eq!(d[9 + 1], 1.0);
        assert_eq!(d[4 * 9 + 4], 4.0);
    }
}
