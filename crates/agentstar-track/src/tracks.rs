//! 3-D point tracks from a tracked model: query pixels of one keyframe are lifted onto the
//! rendered model surface, attached to the part they hit, and carried through every keyframe
//! by that part's pose, in each keyframe's camera (metres with the run's scale). Each point
//! is marked visible where it is the nearest surface at its own pixel.

use crate::update::GenPose;
use agentstar_geom::pose::Similarity;
use agentstar_geom::{ObjectModel, PinholeCamera, Point3};
use agentstar_render::{render_full, PosedModel, RenderBuffers};

/// Tracks of `queries.len()` points through `points.len()` keyframes.
#[derive(Debug, Clone, PartialEq)]
pub struct PointTracks {
    pub query_frame: usize,
    /// Pixel coordinates (u, v) in the query frame (pixel centres are at +0.5).
    pub queries_px: Vec<[f64; 2]>,
    /// The part each query landed on.
    pub parts: Vec<usize>,
    /// `points[frame][query]`: camera-frame position (metres with the run's scale).
    pub points: Vec<Vec<[f64; 3]>>,
    /// `visible[frame][query]`: the point is the nearest surface at its projection.
    pub visible: Vec<Vec<bool>>,
}

fn camera_from_parts(model: &ObjectModel, scale: f64, g: &GenPose) -> Vec<Similarity> {
    let cam = g.pose.with_scale(scale);
    model
        .tree
        .part_transforms(&g.states)
        .iter()
        .map(|t| cam.compose(&Similarity::from_rigid(t)))
        .collect()
}

fn visible(b: &RenderBuffers, camera: &PinholeCamera, p: &Point3, part: usize) -> bool {
    let Some((u, v)) = camera.project(p) else {
        return false;
    };
    if u < 0.0 || v < 0.0 || u >= b.width as f64 || v >= b.height as f64 {
        return false;
    }
    let k = (v as u32 * b.width + u as u32) as usize;
    let z = b.depth[k] as f64;
    b.part[k] as usize == part && (z - p.z).abs() <= 0.01 * p.z + 1e-4
}

/// Tracks the given query pixels (or, with `queries` empty, every `stride_px`-th covered
/// pixel of the query frame's render). Queries that miss the model are dropped; the returned
/// `queries_px` lists those kept.
pub fn point_tracks(
    model: &ObjectModel,
    scale: f64,
    poses: &[GenPose],
    cameras: &[PinholeCamera],
    query_frame: usize,
    queries: &[[f64; 2]],
    stride_px: u32,
) -> PointTracks {
    let n = poses.len().min(cameras.len());
    let qf = query_frame.min(n.saturating_sub(1));
    let render = |f: usize| {
        render_full(
            &cameras[f],
            &PosedModel::new(model, &poses[f].states, &poses[f].pose.with_scale(scale)).instances,
        )
    };
    let mut out = PointTracks {
        query_frame: qf,
        queries_px: vec![],
        parts: vec![],
        points: vec![vec![]; n],
        visible: vec![vec![]; n],
    };
    if n == 0 {
        return out;
    }
    let b0 = render(qf);
    let cam0 = &cameras[qf];
    let pixels: Vec<[f64; 2]> = if queries.is_empty() {
        let s = stride_px.max(1);
        (0..b0.height)
            .step_by(s as usize)
            .flat_map(|y| (0..b0.width).step_by(s as usize).map(move |x| (x, y)))
            .filter(|&(x, y)| b0.covered(x, y))
            .map(|(x, y)| [x as f64 + 0.5, y as f64 + 0.5])
            .collect()
    } else {
        queries.to_vec()
    };
    let parts0 = camera_from_parts(model, scale, &poses[qf]);
    let mut locals = vec![];
    for q in pixels {
        if !(q[0] >= 0.0 && q[1] >= 0.0 && q[0] < b0.width as f64 && q[1] < b0.height as f64) {
            continue;
        }
        let (x, y) = (q[0] as u32, q[1] as u32);
        if !b0.covered(x, y) {
            continue;
        }
        let k = (y * b0.width + x) as usize;
        let part = b0.part[k] as usize;
        let p = Point3::from(cam0.ray_direction(q[0], q[1]) * b0.depth[k] as f64);
        locals.push((part, parts0[part].inverse().transform_point(&p)));
        out.queries_px.push(q);
        out.parts.push(part);
    }
    for f in 0..n {
        let b = if f == qf { b0.clone() } else { render(f) };
        let parts = camera_from_parts(model, scale, &poses[f]);
        for (part, local) in &locals {
            let p = parts[*part].transform_point(local);
            out.visible[f].push(visible(&b, &cameras[f], &p, *part));
            out.points[f].push([p.x, p.y, p.z]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::pose::ObjectPose;
    use agentstar_geom::primitives::cuboid;
    use agentstar_geom::{KinematicTree, Part, UnitQuaternion, Vector3};

    #[test]
    fn points_ride_on_the_object_and_hide_behind_it() {
        let model = ObjectModel {
            parts: vec![Part::new(
                "cube",
                cuboid(1.0, 1.0, 1.0).expect("cube"),
                [0.5; 3],
            )],
            tree: KinematicTree::rigid(1),
        };
        let cam = PinholeCamera::new(200.0, 200.0, 80.0, 60.0, 160, 120).expect("cam");
        // Frame 1: moved 5 cm right; frame 2: turned half way about the vertical axis.
        let poses: Vec<GenPose> = [
            ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.0, 0.0, 1.0)),
            ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.05, 0.0, 1.0)),
            ObjectPose::new(
                UnitQuaternion::from_axis_angle(&Vector3::y_axis(), std::f64::consts::PI),
                Vector3::new(0.0, 0.0, 1.0),
            ),
        ]
        .into_iter()
        .map(|pose| GenPose {
            pose,
            states: vec![],
        })
        .collect();
        let cams = vec![cam; 3];
        let t = point_tracks(
            &model,
            0.2,
            &poses,
            &cams,
            0,
            &[[80.5, 60.5], [1.5, 1.5]],
            1,
        );
        assert_eq!(t.queries_px, vec![[80.5, 60.5]], "the miss is dropped");
        let p0 = t.points[0][0];
        // The front face of a 0.2 m cube centred 1 m away is at z = 0.9.
        assert!((p0[2] - 0.9).abs() < 1e-6, "{p0:?}");
        let p1 = t.points[1][0];
        assert!((p1[0] - p0[0] - 0.05).abs() < 1e-9 && (p1[2] - p0[2]).abs() < 1e-9);
        assert!(t.visible[0][0] && t.visible[1][0]);
        // After a half turn the point is on the back face, hidden.
        assert!((t.points[2][0][2] - 1.1).abs() < 1e-6);
        assert!(!t.visible[2][0]);
        // A grid of queries covers the face.
        let g = point_tracks(&model, 0.2, &poses, &cams, 0, &[], 4);
        assert!(g.queries_px.len() > 50 && g.points[2].len() == g.queries_px.len());
    }
}
