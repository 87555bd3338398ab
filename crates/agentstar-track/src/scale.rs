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
//! - a stated size: metres along one model axis over the model's extent there.

use crate::TrackError;
use agentstar_geom::pose::Rigid;
use agentstar_geom::Vector3;
use agentstar_render::{DepthObservation, RenderBuffers, ScoreTarget};

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
}
