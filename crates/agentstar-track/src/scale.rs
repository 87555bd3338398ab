//! The object's scale (metres per model unit) from what a capture measures. Rescaling a
//! pose by `k` keeps its rotation and multiplies its translation by `k`: every camera-frame
//! point of the model moves along its ray by `k`, so the silhouettes stay exactly as they
//! were and only metric quantities change. That is why silhouettes alone never say the
//! scale, and what the estimators here measure instead:
//!
//! - depth: the observed depth over the rendered depth at the current scale, over the
//!   visible mask (hands excluded), a median per frame and the median over frames;
//! - parallax: with metric cameras that move around an object that stays put in the world,
//!   the one `k` that puts the object's origin at the same world point in every frame
//!   (linear least squares);
//! - a stated size: metres along one model axis over the model's extent there;
//! - a hand: where hand masks exist and depth does not, the hand's apparent palm breadth
//!   (the widest disc its mask holds) against an adult-hand prior puts the hand at a depth,
//!   and the hand holds the object, so the object's centre is taken to be there. The
//!   weakest route: its uncertainty (the prior's spread, the frames' spread, where the hand
//!   sits within the object's depth) is stated with it.

use crate::TrackError;
use agentstar_geom::pose::Rigid;
use agentstar_geom::Vector3;
use agentstar_render::{BitMask, DepthObservation, RenderBuffers, ScoreTarget};

/// Frames with fewer usable depth pixels than this are left out of the depth estimate.
pub const MIN_DEPTH_PIXELS: usize = 30;

/// A ratio `k`: the new scale is `k ×` the current one.
#[derive(Debug, Clone, PartialEq)]
pub struct ScaleEstimate {
    pub ratio: f64,
    /// Each frame's own ratio (depth), or its object-origin offset from the common point
    /// after the fit, metres (parallax).
    pub per_frame: Vec<(String, f64)>,
    /// Relative spread: the median absolute deviation of the per-frame ratios over the
    /// ratio (depth); the RMS offset over the RMS camera baseline (parallax).
    pub spread: f64,
    /// Pixels (depth) or frames (parallax) used.
    pub samples: usize,
    pub notes: Vec<String>,
}

fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n == 0 {
        f64::NAN
    } else if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// One frame for the depth estimate: the model rendered at its pose and the current scale,
/// the observed depth and the target (mask, hands excluded).
pub struct DepthFrame<'a> {
    pub name: String,
    pub render: &'a RenderBuffers,
    pub observed: &'a DepthObservation,
    pub target: &'a ScoreTarget,
}

/// The ratio of observed to rendered depth over the pixels where the mask, the render and
/// a confident observation (≥ 0.5) meet outside the hands.
pub fn ratio_from_depth(frames: &[DepthFrame<'_>]) -> Result<ScaleEstimate, TrackError> {
    let mut per_frame = vec![];
    let mut samples = 0;
    let mut notes = vec![];
    for f in frames {
        let (r, o) = (f.render, f.observed);
        if (r.width, r.height) != (o.width, o.height) {
            return Err(TrackError::Invalid(format!(
                "frame {}: the depth is {}×{}, the frame {}×{}",
                f.name, o.width, o.height, r.width, r.height
            )));
        }
        let mut ratios = vec![];
        for y in 0..r.height {
            for x in 0..r.width {
                let k = (y * r.width + x) as usize;
                let (zr, zo, c) = (r.depth[k], o.depth[k], o.confidence[k]);
                let usable = zr.is_finite()
                    && zr > 0.0
                    && zo.is_finite()
                    && zo > 0.0
                    && c >= 0.5
                    && f.target.mask().get(x, y)
                    && f.target.keep().is_none_or(|keep| keep.get(x, y));
                if usable {
                    ratios.push(zo as f64 / zr as f64);
                }
            }
        }
        if ratios.len() < MIN_DEPTH_PIXELS {
            notes.push(format!(
                "{}: {} usable depth pixel(s), left out",
                f.name,
                ratios.len()
            ));
            continue;
        }
        samples += ratios.len();
        per_frame.push((f.name.clone(), median(&mut ratios)));
    }
    if per_frame.is_empty() {
        return Err(TrackError::Invalid(
            "no keyframe has enough depth where the model and the mask meet (is there depth in the capture, and are the poses close?)".into(),
        ));
    }
    let mut ks: Vec<f64> = per_frame.iter().map(|(_, k)| *k).collect();
    let ratio = median(&mut ks);
    let mut dev: Vec<f64> = ks.iter().map(|k| (k - ratio).abs()).collect();
    let spread = median(&mut dev) / ratio;
    if spread > 0.05 {
        notes.push(format!(
            "the frames disagree by {:.1}% (median absolute deviation): check the poses of the outliers",
            100.0 * spread
        ));
    }
    Ok(ScaleEstimate {
        ratio,
        per_frame,
        spread,
        samples,
        notes,
    })
}

/// One frame for the parallax estimate: the metric camera and the object's origin in that
/// camera at the current scale (metres; the pose's translation).
pub struct ParallaxFrame {
    pub name: String,
    pub world_from_camera: Rigid,
    pub origin_in_camera: Vector3,
}

/// The `k` that puts the object's origin, `C_i + k · R_i · o_i` in the world, at one point
/// in every frame. Needs an object that stays put and a camera that moves.
pub fn ratio_from_parallax(frames: &[ParallaxFrame]) -> Result<ScaleEstimate, TrackError> {
    if frames.len() < 2 {
        return Err(TrackError::Invalid(
            "parallax needs at least two keyframes".into(),
        ));
    }
    let n = frames.len() as f64;
    let centres: Vec<Vector3> = frames
        .iter()
        .map(|f| f.world_from_camera.translation.vector)
        .collect();
    let rays: Vec<Vector3> = frames
        .iter()
        .map(|f| f.world_from_camera.rotation * f.origin_in_camera)
        .collect();
    let c_mean = centres.iter().sum::<Vector3>() / n;
    let u_mean = rays.iter().sum::<Vector3>() / n;
    let (mut num, mut den) = (0.0, 0.0);
    for (c, u) in centres.iter().zip(&rays) {
        num += (u - u_mean).dot(&(c - c_mean));
        den += (u - u_mean).norm_squared();
    }
    let baseline = (centres
        .iter()
        .map(|c| (c - c_mean).norm_squared())
        .sum::<f64>()
        / n)
        .sqrt();
    let distance = rays.iter().map(|u| u.norm()).sum::<f64>() / n;
    if den <= 1e-18 || baseline < 1e-9 {
        return Err(TrackError::Invalid(
            "the camera does not move relative to the object: parallax cannot measure the scale (use depth or a stated size)".into(),
        ));
    }
    let ratio = -num / den;
    if !(ratio.is_finite() && ratio > 0.0) {
        return Err(TrackError::Invalid(format!(
            "parallax gives no positive scale (ratio {ratio:.4}): the object moves in the world, or the cameras are not metric"
        )));
    }
    let points: Vec<Vector3> = centres
        .iter()
        .zip(&rays)
        .map(|(c, u)| c + u * ratio)
        .collect();
    let p_mean = points.iter().sum::<Vector3>() / n;
    let offsets: Vec<f64> = points.iter().map(|p| (p - p_mean).norm()).collect();
    let rms = (offsets.iter().map(|o| o * o).sum::<f64>() / n).sqrt();
    let spread = rms / baseline;
    let mut notes = vec![];
    if baseline < 0.05 * distance * ratio {
        notes.push(format!(
            "the camera moved {:.3} m (RMS) at {:.3} m from the object: a short baseline, the estimate is weak",
            baseline,
            distance * ratio
        ));
    }
    if spread > 0.2 {
        notes.push(format!(
            "after the fit the object's origin still wanders {:.1}% of the camera baseline: it moves in the world (parallax assumes it stays put), or some poses are off",
            100.0 * spread
        ));
    }
    Ok(ScaleEstimate {
        ratio,
        per_frame: frames
            .iter()
            .zip(offsets)
            .map(|(f, o)| (f.name.clone(), o))
            .collect(),
        spread,
        samples: frames.len(),
        notes,
    })
}

/// The adult hand's breadth across the palm at the knuckles (metacarpal hand breadth),
/// metres: about 8.4 cm for men and 7.4 cm for women in adult anthropometric surveys, each
/// with a spread of about 0.4–0.5 cm; the pooled mean of the two.
pub const PALM_BREADTH_MEAN_M: f64 = 0.079;
/// The pooled spread (one standard deviation) of [`PALM_BREADTH_MEAN_M`], metres: the
/// sexes' own spread and the half-difference of their means together.
pub const PALM_BREADTH_SD_M: f64 = 0.0065;
/// Hands narrower than this (pixels) are not measured: a pixel is then over a tenth of it.
pub const MIN_PALM_PX: f64 = 10.0;

/// One frame for the hand estimate: its hand mask, the camera's focal length and where
/// the object's centre is at the current scale.
pub struct HandFrame<'a> {
    pub name: String,
    pub hand: &'a BitMask,
    /// Focal length, pixels (the geometric mean of fx and fy).
    pub focal_px: f64,
    /// Camera-frame depth of the object's bounding-box centre at the current scale, metres.
    pub object_depth_m: f64,
    /// Half the diagonal of the object's bounding box at the current scale, metres.
    pub object_radius_m: f64,
}

/// The palm's apparent breadth in a hand mask, pixels: the diameter of the largest disc
/// the mask holds (the palm is the widest part of a hand; fingers and thumb are narrower),
/// from an exact Euclidean distance transform, the image's outside counting as background.
/// Returns the breadth and the disc's centre; `None` for an empty mask.
pub fn palm_breadth_px(mask: &BitMask) -> Option<(f64, (u32, u32))> {
    let (w, h) = (mask.width() as usize, mask.height() as usize);
    if w == 0 || h == 0 || mask.count() == 0 {
        return None;
    }
    // Squared distance to the nearest background pixel centre, columns then rows
    // (Felzenszwalb and Huttenlocher's lower envelope of parabolas).
    let far = ((w * w + h * h) as f64) * 4.0;
    let mut d2 = vec![0.0f64; w * h];
    let mut column = vec![0.0f64; h + 2];
    let mut out = vec![0.0f64; h + 2];
    for x in 0..w {
        // Background rows −1 and h stand for the outside of the image.
        column[0] = 0.0;
        column[h + 1] = 0.0;
        for y in 0..h {
            column[y + 1] = if mask.get(x as u32, y as u32) {
                far
            } else {
                0.0
            };
        }
        envelope(&column, &mut out);
        for y in 0..h {
            d2[y * w + x] = out[y + 1];
        }
    }
    let mut row = vec![0.0f64; w + 2];
    let mut out = vec![0.0f64; w + 2];
    let mut best = (0.0f64, (0u32, 0u32));
    for y in 0..h {
        row[0] = 0.0;
        row[w + 1] = 0.0;
        row[1..=w].copy_from_slice(&d2[y * w..(y + 1) * w]);
        envelope(&row, &mut out);
        for x in 0..w {
            if out[x + 1] > best.0 {
                best = (out[x + 1], (x as u32, y as u32));
            }
        }
    }
    // A strip W pixels wide has its middle pixel W / 2 (W even) or (W + 1) / 2 (W odd) from
    // the nearest background: 2d − ½ is W within half a pixel.
    Some((2.0 * best.0.sqrt() - 0.5, best.1))
}

/// The 1-D squared distance transform of sampled values `f` (0 on background, large
/// inside): `out[q] = min_p (q − p)² + f[p]`.
fn envelope(f: &[f64], out: &mut [f64]) {
    let n = f.len();
    let mut v = vec![0usize; n];
    let mut z = vec![0.0f64; n + 1];
    let mut k = 0usize;
    z[0] = f64::NEG_INFINITY;
    z[1] = f64::INFINITY;
    let parabola_cut = |q: usize, p: usize| {
        ((f[q] + (q * q) as f64) - (f[p] + (p * p) as f64)) / (2.0 * (q - p) as f64)
    };
    for q in 1..n {
        let mut s = parabola_cut(q, v[k]);
        // z[0] is −∞, so k never goes below 0 (every value is finite).
        while s <= z[k] && k > 0 {
            k -= 1;
            s = parabola_cut(q, v[k]);
        }
        k += 1;
        v[k] = q;
        z[k] = s;
        z[k + 1] = f64::INFINITY;
    }
    let mut k = 0usize;
    for (q, o) in out.iter_mut().enumerate().take(n) {
        while z[k + 1] < q as f64 {
            k += 1;
        }
        let p = v[k];
        let d = q as f64 - p as f64;
        *o = d * d + f[p];
    }
}

/// A hand estimate: the ratio and its stated uncertainty.
#[derive(Debug, Clone, PartialEq)]
pub struct HandScale {
    pub estimate: ScaleEstimate,
    /// One standard deviation of the ratio, relative: the prior's spread, the frames'
    /// spread over their number and where the hand sits within the object's depth.
    pub uncertainty: f64,
    /// Each frame's palm breadth, pixels, in the order of `estimate.per_frame`.
    pub palm_px: Vec<f64>,
}

/// The ratio that puts the object's centre at the depth where an adult palm
/// ([`PALM_BREADTH_MEAN_M`]) looks as broad as each frame's hand mask (its widest disc):
/// per frame `f · B / breadth / depth`, the median over frames.
pub fn ratio_from_hand(frames: &[HandFrame<'_>]) -> Result<HandScale, TrackError> {
    let mut per_frame = vec![];
    let mut palm_px = vec![];
    let mut placement = vec![];
    let mut notes = vec![];
    let mut small = vec![];
    for f in frames {
        if !(f.focal_px.is_finite() && f.focal_px > 0.0) {
            return Err(TrackError::Invalid(format!(
                "frame {}: the camera's focal length {} px is not positive",
                f.name, f.focal_px
            )));
        }
        if !(f.object_depth_m.is_finite() && f.object_depth_m > 0.0) {
            notes.push(format!(
                "{}: the object's centre is not in front of the camera ({:.4} m), left out",
                f.name, f.object_depth_m
            ));
            continue;
        }
        let Some((breadth, _)) = palm_breadth_px(f.hand) else {
            continue;
        };
        if breadth < MIN_PALM_PX {
            small.push(f.name.clone());
            continue;
        }
        let hand_depth = f.focal_px * PALM_BREADTH_MEAN_M / breadth;
        per_frame.push((f.name.clone(), hand_depth / f.object_depth_m));
        palm_px.push(breadth);
        placement.push(f.object_radius_m / f.object_depth_m);
    }
    if !small.is_empty() {
        notes.push(format!(
            "hands under {MIN_PALM_PX} px across left out: {}",
            small.join(", ")
        ));
    }
    if per_frame.is_empty() {
        return Err(TrackError::Invalid(format!(
            "no keyframe has a hand mask with a palm {MIN_PALM_PX} px or more across (mask_hand/ is empty or missing for the frames asked): the hand route needs hands"
        )));
    }
    let n = per_frame.len();
    let mut ks: Vec<f64> = per_frame.iter().map(|(_, k)| *k).collect();
    let ratio = median(&mut ks);
    let mut dev: Vec<f64> = ks.iter().map(|k| (k - ratio).abs()).collect();
    // The median absolute deviation as a standard deviation, relative.
    let spread = 1.4826 * median(&mut dev) / ratio;
    let prior = PALM_BREADTH_SD_M / PALM_BREADTH_MEAN_M;
    // The hand touches the object somewhere within its radius of the centre, nearer or
    // farther: uniform over ±radius, relative to the depth.
    let place = median(&mut placement) / 3f64.sqrt();
    let measured = if n > 1 {
        spread / (n as f64).sqrt()
    } else {
        // One frame says nothing of its own spread: a tenth, a palm's tilt.
        0.1
    };
    let uncertainty = (prior * prior + place * place + measured * measured).sqrt();
    if n < 3 {
        notes.push(format!(
            "only {n} frame(s) show a hand: the estimate rests on how these hands are turned"
        ));
    }
    if spread > 0.2 {
        notes.push(format!(
            "the frames disagree by {:.0}% (one standard deviation): hands turned edge-on or half hidden look narrower; check the outliers",
            100.0 * spread
        ));
    }
    Ok(HandScale {
        estimate: ScaleEstimate {
            ratio,
            per_frame,
            spread,
            samples: n,
            notes,
        },
        uncertainty,
        palm_px,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::nalgebra::{Translation3, UnitQuaternion};

    #[test]
    fn parallax_finds_the_scale_that_keeps_a_static_object_in_place() {
        // An object at a world point, seen by cameras on an arc; the poses' translations are
        // 0.8 of the truth (the scale 20% short), so the true ratio is 1.25.
        let object = Vector3::new(0.1, -0.05, 0.3);
        let frames: Vec<ParallaxFrame> = (0..6)
            .map(|i| {
                let a = 0.2 * i as f64;
                let centre = Vector3::new(0.6 * a.sin(), 0.05 * i as f64, -0.6 * a.cos());
                let rot = UnitQuaternion::from_euler_angles(0.1 * a, -a, 0.02);
                let w_from_c = Rigid::from_parts(Translation3::from(centre), rot);
                let in_cam = w_from_c.inverse() * agentstar_geom::Point3::from(object);
                ParallaxFrame {
                    name: format!("{i}"),
                    world_from_camera: w_from_c,
                    origin_in_camera: in_cam.coords * 0.8,
                }
            })
            .collect();
        let e = ratio_from_parallax(&frames).expect("estimate");
        assert!((e.ratio - 1.25).abs() < 1e-9, "{e:?}");
        assert!(e.spread < 1e-9 && e.notes.is_empty(), "{e:?}");
        // A static camera says so.
        let still: Vec<ParallaxFrame> = frames
            .iter()
            .map(|f| ParallaxFrame {
                name: f.name.clone(),
                world_from_camera: frames[0].world_from_camera,
                origin_in_camera: f.origin_in_camera,
            })
            .collect();
        let e = ratio_from_parallax(&still);
        assert!(e.is_err() || e.expect("e").notes.iter().any(|n| n.contains("moves")));
    }

    #[test]
    fn depth_ratios_are_medians_over_the_mask() {
        let (w, h) = (20u32, 10u32);
        let n = (w * h) as usize;
        let mut render = RenderBuffers::new(w, h);
        let mut mask = agentstar_render::BitMask::new(w, h);
        for y in 2..8 {
            for x in 4..16 {
                render.depth[(y * w + x) as usize] = 0.5;
                mask.set(x, y);
            }
        }
        let mut depth = vec![0.6f32; n];
        // A few outliers (the background at the mask's edge) do not move a median.
        for x in 4..8 {
            depth[(2 * w + x) as usize] = 3.0;
        }
        let observed = DepthObservation {
            width: w,
            height: h,
            depth,
            confidence: vec![1.0; n],
        };
        let target = ScoreTarget::new(mask, None).expect("target");
        let e = ratio_from_depth(&[DepthFrame {
            name: "a".into(),
            render: &render,
            observed: &observed,
            target: &target,
        }])
        .expect("estimate");
        assert!((e.ratio - 1.2).abs() < 1e-6, "{e:?}");
        assert_eq!(e.samples, 72);
    }

    #[test]
    fn the_palm_is_the_widest_disc_of_the_mask() {
        // A 30 px square palm with 8 px fingers and a thumb: the breadth is the palm's.
        let mask = BitMask::from_fn(120, 100, |x, y| {
            let palm = (40..70).contains(&x) && (40..70).contains(&y);
            let finger =
                (10..40).contains(&y) && [42, 52, 62].iter().any(|&f| (f..f + 8).contains(&x));
            let thumb = (20..40).contains(&x) && (55..63).contains(&y);
            palm || finger || thumb
        });
        let (b, (cx, cy)) = palm_breadth_px(&mask).expect("a hand");
        assert!((b - 30.0).abs() <= 0.5, "{b}");
        assert!((40..70).contains(&cx) && (40..70).contains(&cy));
        // A disc of radius 20 measures 40 within two pixels (its digital edge).
        let disc = BitMask::from_fn(100, 100, |x, y| {
            let (dx, dy) = (x as f64 + 0.5 - 50.0, y as f64 + 0.5 - 50.0);
            dx * dx + dy * dy <= 400.0
        });
        let (b, _) = palm_breadth_px(&disc).expect("disc");
        assert!((b - 40.0).abs() <= 2.0, "{b}");
        // The image border is background: a hand cut by it is no wider than what shows.
        let edge = BitMask::from_fn(50, 50, |x, _| x < 6);
        assert!((palm_breadth_px(&edge).expect("edge").0 - 6.0).abs() <= 0.5);
        assert!(palm_breadth_px(&BitMask::new(10, 10)).is_none());
    }

    #[test]
    fn a_palm_of_the_prior_breadth_puts_the_object_at_its_depth() {
        // Hands 40 px across at f = 500 px sit at 500 · 0.079 / 40 m; the object is
        // posed at 0.6 of that, so the ratio is 1 / 0.6 (within the half pixel of a breadth).
        let hand = BitMask::from_fn(200, 200, |x, y| {
            (50..90).contains(&x) && (60..100).contains(&y)
        });
        let depth = 500.0 * PALM_BREADTH_MEAN_M / 40.0;
        let frames: Vec<HandFrame<'_>> = (0..4)
            .map(|i| HandFrame {
                name: format!("{i}"),
                hand: &hand,
                focal_px: 500.0,
                object_depth_m: 0.6 * depth,
                object_radius_m: 0.05 * depth,
            })
            .collect();
        let e = ratio_from_hand(&frames).expect("estimate");
        assert!((e.estimate.ratio * 0.6 - 1.0).abs() < 0.6 / 39.5, "{e:?}");
        assert!(e.uncertainty > PALM_BREADTH_SD_M / PALM_BREADTH_MEAN_M);
        assert!(e.uncertainty < 0.15, "{e:?}");
        // No hands: a clear error.
        let none = BitMask::new(200, 200);
        let err = ratio_from_hand(&[HandFrame {
            name: "a".into(),
            hand: &none,
            focal_px: 500.0,
            object_depth_m: 1.0,
            object_radius_m: 0.1,
        }])
        .expect_err("no hand");
        assert!(err.to_string().contains("hand"), "{err}");
    }
}
