//! Which fixed proportion the silhouettes point at: residuals of a shape grouped by viewing
//! direction.
//!
//! A model's projected extent along an image direction `u` is, for a box-like body, about
//! `Σ_B D_B · |u · J e_B|`: each model axis `B` (size `D_B` along it) projected through the
//! camera's Jacobian `J` at the body's centre. A relative error `δ_B` of size `B` changes it
//! by `δ_B · D_B · |u · J e_B|`. So the observed mask's extent minus the model silhouette's
//! along the projected axes of every frame is a linear system in `(δ_X, δ_Y, δ_Z)`. Solved
//! over the frames that see the model face-on along one axis, it says what those frames
//! want of the other two; solved over all frames, what they want together. Frames that see
//! an axis edge-on and frames that see it face-on disagreeing is the mark of a wrong fixed
//! proportion that a fit on other parameters cannot repair, and that poses fitted to the
//! wrong shape hold where it is.
//!
//! A uniform `δ` is a change of the scale, which silhouettes never say (the poses' depth
//! absorbs it): only the differences between the axes mean something, and the report gives
//! both.

use agentstar_geom::nalgebra::{DMatrix, DVector};
use agentstar_geom::pose::Similarity;
use agentstar_geom::{PinholeCamera, Point3, Vector3};
use agentstar_render::BitMask;

/// An axis counts as face-on within this angle of the ray to the camera (either way).
pub const FACE_ON_DEG: f64 = 30.0;
/// Extents are taken between these quantiles of the pixels' projections, so that a stray
/// pixel of either mask does not set them.
const EXTENT_QUANTILE: f64 = 0.005;
/// A projected axis shorter than this (pixels over the model's size along it) is not a
/// direction to measure along.
const MIN_AXIS_PX: f64 = 6.0;
/// A column of the system with less than this share of the strongest column's weight is
/// not determined by the frames (an axis they all see end-on).
const MIN_COLUMN_SHARE: f64 = 0.05;

/// One frame: the camera, the observed mask and the pixels to count (hands excluded), the
/// model's silhouette, and where the model is.
pub struct ViewFrame<'a> {
    pub name: String,
    pub camera: PinholeCamera,
    pub mask: &'a BitMask,
    /// Pixels that count (`None`: all).
    pub keep: Option<&'a BitMask>,
    pub silhouette: &'a BitMask,
    /// Object → camera, the scale included.
    pub camera_from_object: Similarity,
    /// The bounding box's centre (object frame) and its size along X, Y, Z (object units).
    pub centre: Point3,
    pub size: Vector3,
}

/// What one group of frames wants of each axis: the relative change of the model's size
/// along X, Y, Z (`None` where these frames cannot tell).
#[derive(Debug, Clone, PartialEq)]
pub struct AxisWants {
    pub want: [Option<f64>; 3],
    /// Equations (frame × measured direction) behind it.
    pub equations: usize,
}

/// Frames grouped by the model axis they see face-on.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewGroup {
    /// `X`, `Y`, `Z`, or `oblique` (no axis within [`FACE_ON_DEG`] of the ray).
    pub face_on: String,
    pub frames: Vec<String>,
    pub wants: AxisWants,
}

/// One frame's own figures: the axis it sees face-on and, along each projected axis, the
/// observed extent over the model's (pixels over pixels).
#[derive(Debug, Clone, PartialEq)]
pub struct FrameExtents {
    pub frame: String,
    pub face_on: String,
    pub extent_ratio: [Option<f64>; 3],
}

#[derive(Debug, Clone, PartialEq)]
pub struct ViewResiduals {
    pub all: AxisWants,
    pub groups: Vec<ViewGroup>,
    pub frames: Vec<FrameExtents>,
}

/// The quantile extent of `mask ∧ keep` along the unit image direction `u`, pixels.
fn extent_along(mask: &BitMask, keep: Option<&BitMask>, u: [f64; 2]) -> Option<f64> {
    let mut proj = vec![];
    for y in 0..mask.height() {
        for x in 0..mask.width() {
            if mask.get(x, y) && keep.is_none_or(|k| k.get(x, y)) {
                proj.push((x as f64 + 0.5) * u[0] + (y as f64 + 0.5) * u[1]);
            }
        }
    }
    if proj.len() < 20 {
        return None;
    }
    proj.sort_by(f64::total_cmp);
    let n = proj.len() - 1;
    let at = |q: f64| proj[(q * n as f64).round() as usize];
    Some(at(1.0 - EXTENT_QUANTILE) - at(EXTENT_QUANTILE) + 1.0)
}

/// The image-plane change (pixels) of moving unit length along camera-frame direction `d`
/// at camera-frame point `p`: the projection's Jacobian.
fn project_direction(cam: &PinholeCamera, p: &Point3, d: &Vector3) -> [f64; 2] {
    let z = p.z;
    [
        cam.fx * (d.x - p.x / z * d.z) / z,
        cam.fy * (d.y - p.y / z * d.z) / z,
    ]
}

/// The relative size changes along the determined axes that best explain `rows`
/// (`[a_X, a_Y, a_Z, residual]`), least squares; the axis `end_on` (seen end-on by every
/// frame of a group) is left out.
fn solve(rows: &[[f64; 4]], end_on: Option<usize>) -> AxisWants {
    let mut weight = [0.0f64; 3];
    for r in rows {
        for b in 0..3 {
            weight[b] += r[b] * r[b];
        }
    }
    let strongest = weight.iter().copied().fold(0.0, f64::max);
    let cols: Vec<usize> = (0..3)
        .filter(|&b| Some(b) != end_on)
        .filter(|&b| strongest > 0.0 && weight[b] >= MIN_COLUMN_SHARE * strongest)
        .collect();
    let mut want = [None; 3];
    if cols.is_empty() || rows.len() < cols.len() {
        return AxisWants {
            want,
            equations: rows.len(),
        };
    }
    let a = DMatrix::from_fn(rows.len(), cols.len(), |i, j| rows[i][cols[j]]);
    let b = DVector::from_fn(rows.len(), |i, _| rows[i][3]);
    if let Ok(x) = a.svd(true, true).solve(&b, 1e-9) {
        for (j, &c) in cols.iter().enumerate() {
            if x[j].is_finite() {
                want[c] = Some(x[j]);
            }
        }
    }
    AxisWants {
        want,
        equations: rows.len(),
    }
}

/// Residuals of the silhouettes against the masks, grouped by the axis each frame sees
/// face-on, as relative size changes along the model's axes.
pub fn view_residuals(frames: &[ViewFrame<'_>]) -> ViewResiduals {
    const NAMES: [&str; 3] = ["X", "Y", "Z"];
    let mut per_frame = vec![];
    let mut rows_of: Vec<(String, Vec<[f64; 4]>)> = vec![];
    let mut all_rows = vec![];
    for f in frames {
        let pose = &f.camera_from_object;
        let centre = pose.transform_point(&f.centre);
        if !centre.z.is_finite() || centre.z <= 1e-9 {
            continue;
        }
        // Unit model axes in the camera frame, and their image projections per unit size.
        let axes: Vec<Vector3> = (0..3)
            .map(|b| pose.rotation * Vector3::ith(b, 1.0))
            .collect();
        let toward = -centre.coords.normalize();
        let face_on = (0..3)
            .map(|b| (b, axes[b].dot(&toward).abs()))
            .filter(|&(_, c)| c >= FACE_ON_DEG.to_radians().cos())
            .max_by(|a, b| a.1.total_cmp(&b.1))
            .map_or("oblique".to_string(), |(b, _)| NAMES[b].to_string());
        // Pixels per object unit along each axis, times its size: the axis's projection.
        let proj: Vec<[f64; 2]> = (0..3)
            .map(|b| {
                let j = project_direction(&f.camera, &centre, &axes[b]);
                let len = f.size[b] * pose.scale;
                [j[0] * len, j[1] * len]
            })
            .collect();
        let mut ratios = [None; 3];
        let mut rows = vec![];
        for a in 0..3 {
            let n = (proj[a][0].powi(2) + proj[a][1].powi(2)).sqrt();
            if n < MIN_AXIS_PX {
                continue;
            }
            let u = [proj[a][0] / n, proj[a][1] / n];
            let (Some(observed), Some(model)) = (
                extent_along(f.mask, f.keep, u),
                extent_along(f.silhouette, f.keep, u),
            ) else {
                continue;
            };
            ratios[a] = Some(observed / model);
            let mut row = [0.0; 4];
            for b in 0..3 {
                row[b] = (u[0] * proj[b][0] + u[1] * proj[b][1]).abs();
            }
            row[3] = observed - model;
            rows.push(row);
        }
        all_rows.extend_from_slice(&rows);
        match rows_of.iter_mut().find(|(k, _)| *k == face_on) {
            Some((_, r)) => r.extend(rows),
            None => rows_of.push((face_on.clone(), rows)),
        }
        per_frame.push(FrameExtents {
            frame: f.name.clone(),
            face_on,
            extent_ratio: ratios,
        });
    }
    let mut groups: Vec<ViewGroup> = rows_of
        .into_iter()
        .map(|(face_on, rows)| ViewGroup {
            frames: per_frame
                .iter()
                .filter(|p| p.face_on == face_on)
                .map(|p| p.frame.clone())
                .collect(),
            wants: solve(&rows, NAMES.iter().position(|n| *n == face_on)),
            face_on,
        })
        .collect();
    groups.sort_by(|a, b| a.face_on.cmp(&b.face_on));
    ViewResiduals {
        all: solve(&all_rows, None),
        groups,
        frames: per_frame,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{ObjectModel, Part, UnitQuaternion};
    use agentstar_render::{PosedModel, SilhouetteRenderer};

    fn slab(x: f64, y: f64, z: f64) -> ObjectModel {
        let part = Part::new("body", cuboid(x, y, z).expect("box"), [0.5; 3]);
        ObjectModel {
            parts: vec![part],
            tree: agentstar_geom::KinematicTree::new(vec![], &["body".to_string()]).expect("tree"),
        }
    }

    #[test]
    fn a_model_too_short_along_x_is_named_by_the_frames_that_see_x_edge_on() {
        // The truth is 1.0 × 0.6 × 0.4; the model is 0.9 × 0.6 × 0.4 (X 10% short). Frames
        // from many directions, the model at the true pose.
        let (truth, model) = (slab(1.0, 0.6, 0.4), slab(0.9, 0.6, 0.4));
        let cam = PinholeCamera::new(400.0, 400.0, 160.0, 120.0, 320, 240).expect("camera");
        let mut masks = vec![];
        let mut poses = vec![];
        for k in 0..8 {
            let rot = UnitQuaternion::from_euler_angles(0.4 * k as f64, 0.9 * k as f64, 0.3);
            let pose = Similarity {
                scale: 0.2,
                rotation: rot,
                translation: Vector3::new(0.0, 0.0, 1.0),
            };
            let render = |m: &ObjectModel| {
                let posed = PosedModel::new(m, &[], &pose);
                SilhouetteRenderer::new(320, 240)
                    .render(&cam, &posed.instances)
                    .clone()
            };
            masks.push((render(&truth), render(&model)));
            poses.push(pose);
        }
        let frames: Vec<ViewFrame<'_>> = masks
            .iter()
            .zip(&poses)
            .enumerate()
            .map(|(k, ((mask, sil), pose))| ViewFrame {
                name: format!("{k}"),
                camera: cam,
                mask,
                keep: None,
                silhouette: sil,
                camera_from_object: *pose,
                centre: Point3::origin(),
                size: Vector3::new(0.9, 0.6, 0.4),
            })
            .collect();
        let r = view_residuals(&frames);
        let [x, y, z] = r.all.want;
        let (x, y, z) = (x.expect("x"), y.expect("y"), z.expect("z"));
        // X wants ~ +11% (1.0 / 0.9), the others about nothing.
        assert!((x - 0.111).abs() < 0.04, "{r:?}");
        assert!(y.abs() < 0.03 && z.abs() < 0.03, "{r:?}");
        // A group never judges the axis it sees end-on.
        for g in &r.groups {
            if let Some(b) = ["X", "Y", "Z"].iter().position(|n| *n == g.face_on) {
                assert!(g.wants.want[b].is_none(), "{g:?}");
            }
        }
        // The right model wants nothing.
        let same: Vec<ViewFrame<'_>> = masks
            .iter()
            .zip(&poses)
            .map(|((mask, _), pose)| ViewFrame {
                name: "t".into(),
                camera: cam,
                mask,
                keep: None,
                silhouette: mask,
                camera_from_object: *pose,
                centre: Point3::origin(),
                size: Vector3::new(1.0, 0.6, 0.4),
            })
            .collect();
        let r = view_residuals(&same);
        assert!(
            r.all.want.iter().all(|w| w.is_some_and(|w| w.abs() < 1e-9)),
            "{r:?}"
        );
        assert_eq!(r.frames.len(), 8);
    }
}
