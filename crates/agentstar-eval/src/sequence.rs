//! Every metric of one sequence: renders ground truth and prediction in each keyframe's
//! camera, aligns the monocular scale, and computes EPE (ARCTIC), Chamfer (whole, moving,
//! static parts), gauge-aligned rigid pose errors (HOT3D) and articulation errors (iTACO).
//!
//! Joint matching rule: a ground-truth joint is matched to the predicted joint that moves a
//! part of the same name as its child part; failing that, to the predicted joint whose moving
//! parts' centroid lies nearest the ground-truth child part's centroid in the first keyframe.

use crate::articulation::{axis_angle_error, axis_line_distance, state_error};
use crate::chamfer::{chamfer_both, sample_surface};
use crate::rigid::{gauge_aligned_errors, GaugeErrors};
use crate::scale::median_log_depth_scale;
use agentstar_geom::model::transform_rigid;
use agentstar_geom::pose::{GenPose, ObjectPose, Similarity};
use agentstar_geom::{KinematicTree, ObjectModel, Part, PinholeCamera, Point3, TriMesh};
use agentstar_render::raster::Affine;
use agentstar_render::{render_full, Instance, PosedModel, RenderBuffers};

pub use agentstar_geom::truth::{GtJoint, GtSequence};

/// A prediction: the object model, its shared scale and its generalised pose per keyframe.
#[derive(Debug, Clone)]
pub struct PredSequence<'a> {
    pub model: &'a ObjectModel,
    pub scale: f64,
    pub poses: Vec<GenPose>,
}

#[derive(Debug, Clone, Copy)]
pub struct EvalConfig {
    pub samples: usize,
    pub epe_queries: usize,
    pub seed: u64,
}

impl Default for EvalConfig {
    fn default() -> Self {
        EvalConfig {
            samples: 10_000,
            epe_queries: 1000,
            seed: 7,
        }
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct JointMetrics {
    pub gt_joint: String,
    pub pred_joint: Option<String>,
    pub matched_by: &'static str,
    /// True for a revolute ground-truth joint, false for a prismatic one.
    pub revolute: bool,
    pub axis_angle_rad: Option<f64>,
    /// Metres; revolute joints only.
    pub axis_distance_m: Option<f64>,
    /// Radians or metres.
    pub state_error: Option<f64>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct SequenceMetrics {
    pub frames: usize,
    pub scale_alignment: f64,
    pub epe_cm: Option<f64>,
    pub epe_points: usize,
    pub chamfer_cm: Option<f64>,
    pub cd_moving_cm: Option<f64>,
    pub cd_static_cm: Option<f64>,
    /// The iTACO table's squared Chamfer (m²: mean squared distances, both directions
    /// summed) on the whole object, the moving parts and the static part.
    pub cd_sq_whole_m2: Option<f64>,
    pub cd_sq_moving_m2: Option<f64>,
    pub cd_sq_static_m2: Option<f64>,
    pub rigid: Option<GaugeErrors>,
    pub joints: Vec<JointMetrics>,
}

fn gt_model(gt: &GtSequence) -> ObjectModel {
    let parts: Vec<Part> = gt
        .part_names
        .iter()
        .zip(&gt.meshes)
        .map(|(n, m)| Part::new(n.clone(), m.clone(), [0.5; 3]))
        .collect();
    ObjectModel {
        tree: KinematicTree::rigid(parts.len()),
        parts,
    }
}

fn gt_buffers(model: &ObjectModel, poses: &[ObjectPose], cam: &PinholeCamera) -> RenderBuffers {
    let inst: Vec<Instance> = model
        .parts
        .iter()
        .zip(poses)
        .enumerate()
        .map(|(i, (p, pose))| Instance {
            mesh: &p.mesh,
            bounds: p.bounds,
            camera_from_mesh: Affine::from_similarity(&pose.with_scale(1.0)),
            edges: p.edges.as_deref().map(|e| e.as_slice()),
            open_edges: p.open_edges.as_deref().map(|e| e.as_slice()),
            planes: p.planes.as_deref().map(|q| q.as_slice()),
            part_id: i as u16,
        })
        .collect();
    render_full(cam, &inst)
}

/// `camera_from_part` of every predicted part, before scale alignment.
fn pred_part_transforms(pred: &PredSequence<'_>, f: usize) -> Vec<Similarity> {
    let GenPose { pose, states } = &pred.poses[f];
    let cam = pose.with_scale(pred.scale);
    pred.model
        .tree
        .part_transforms(states)
        .iter()
        .map(|t| cam.compose(&Similarity::from_rigid(t)))
        .collect()
}

fn mesh_points(mesh: &TriMesh, map: impl Fn(&Point3) -> Point3) -> TriMesh {
    TriMesh {
        positions: mesh.positions.iter().map(map).collect(),
        triangles: mesh.triangles.clone(),
    }
}

pub fn evaluate(
    gt: &GtSequence,
    pred: &PredSequence<'_>,
    cameras: &[PinholeCamera],
    cfg: &EvalConfig,
) -> SequenceMetrics {
    let n = cameras.len().min(gt.poses.len()).min(pred.poses.len());
    let gtm = gt_model(gt);
    // Scale alignment over every frame's rendered depths.
    let mut pairs = Vec::new();
    let mut first_buffers = None;
    #[allow(clippy::needless_range_loop)] // three sequences indexed by frame
    for f in 0..n {
        let g = gt_buffers(&gtm, &gt.poses[f], &cameras[f]);
        let GenPose { pose, states } = &pred.poses[f];
        let p = render_full(
            &cameras[f],
            &PosedModel::new(pred.model, states, &pose.with_scale(pred.scale)).instances,
        );
        pairs.extend(
            g.depth
                .iter()
                .zip(&p.depth)
                .map(|(&a, &b)| (a as f64, b as f64)),
        );
        if f == 0 {
            first_buffers = Some((g, p));
        }
    }
    let s_hat = median_log_depth_scale(pairs).unwrap_or(1.0);

    // Chamfer: whole object, moving parts and static parts, per frame.
    let moving_gt: Vec<bool> = (0..gt.meshes.len())
        .map(|i| gt.joints.iter().any(|j| j.child == i))
        .collect();
    let moving_pred: Vec<bool> = (0..pred.model.parts.len())
        .map(|i| pred.model.tree.part_joint(i).is_some())
        .collect();
    let (mut cd_w, mut cd_m, mut cd_s) = (vec![], vec![], vec![]);
    for f in 0..n {
        let gparts: Vec<TriMesh> = gt
            .meshes
            .iter()
            .zip(&gt.poses[f])
            .map(|(m, p)| transform_rigid(m, &p.to_rigid()))
            .collect();
        let pparts: Vec<TriMesh> = pred
            .model
            .parts
            .iter()
            .zip(pred_part_transforms(pred, f))
            .map(|(p, t)| {
                mesh_points(&p.mesh, |q| {
                    Point3::from(t.transform_point(q).coords * s_hat)
                })
            })
            .collect();
        let merged = |parts: &[TriMesh], keep: &dyn Fn(usize) -> bool| {
            let mut m = TriMesh::default();
            for (i, p) in parts.iter().enumerate() {
                if keep(i) {
                    m.append(p);
                }
            }
            m
        };
        let seed = cfg.seed + f as u64;
        let cd = |a: &TriMesh, b: &TriMesh| {
            chamfer_both(
                // Independent samples of the two surfaces: one seed would pick corresponding
                // points on meshes of equal topology and bias the distance low.
                &sample_surface(a, cfg.samples, seed),
                &sample_surface(b, cfg.samples, seed ^ 0x5BD1_E995_0000_0001),
            )
        };
        if let Some(v) = cd(&merged(&gparts, &|_| true), &merged(&pparts, &|_| true)) {
            cd_w.push(v);
        }
        if !gt.joints.is_empty() {
            if let Some(v) = cd(
                &merged(&gparts, &|i| moving_gt[i]),
                &merged(&pparts, &|i| moving_pred[i]),
            ) {
                cd_m.push(v);
            }
            if let Some(v) = cd(
                &merged(&gparts, &|i| !moving_gt[i]),
                &merged(&pparts, &|i| !moving_pred[i]),
            ) {
                cd_s.push(v);
            }
        }
    }
    let mean_of = |v: &[(f64, f64)], sq: bool, unit: f64| {
        (!v.is_empty()).then(|| {
            unit * v.iter().map(|p| if sq { p.1 } else { p.0 }).sum::<f64>() / v.len() as f64
        })
    };
    let mean_cm = |v: &[(f64, f64)]| mean_of(v, false, 100.0);
    let mean_m2 = |v: &[(f64, f64)]| mean_of(v, true, 1.0);

    // EPE: query pixels of the first keyframe carried by their parts.
    let (mut epe, mut epe_points) = (None, 0);
    if let Some((g0, p0)) = &first_buffers {
        let cam = &cameras[0];
        let covered: Vec<(u32, u32)> = (0..g0.height)
            .flat_map(|y| (0..g0.width).map(move |x| (x, y)))
            .filter(|&(x, y)| g0.covered(x, y))
            .collect();
        let stride = ((covered.len() as f64 / cfg.epe_queries.max(1) as f64)
            .sqrt()
            .floor() as u32)
            .max(1);
        let pred_t0 = pred_part_transforms(pred, 0);
        let lift = |b: &RenderBuffers, x: u32, y: u32| -> Option<(usize, Point3)> {
            let k = (y * b.width + x) as usize;
            let z = b.depth[k] as f64;
            b.covered(x, y).then(|| {
                (
                    b.part[k] as usize,
                    Point3::from(cam.ray_direction(x as f64 + 0.5, y as f64 + 0.5) * z),
                )
            })
        };
        let mut queries: Vec<(usize, Point3, usize, Point3)> = Vec::new();
        for &(x, y) in covered
            .iter()
            .filter(|(x, y)| x % stride == 0 && y % stride == 0)
        {
            let Some((gp, gpt)) = lift(g0, x, y) else {
                continue;
            };
            // The nearest pixel of the predicted render (rings outward, up to 64 px).
            let mut found = lift(p0, x, y);
            let mut r = 1i64;
            while found.is_none() && r <= 64 {
                'ring: for dy in -r..=r {
                    for dx in -r..=r {
                        if dx.abs().max(dy.abs()) != r {
                            continue;
                        }
                        let (px, py) = (x as i64 + dx, y as i64 + dy);
                        if px >= 0 && py >= 0 && (px as u32) < p0.width && (py as u32) < p0.height {
                            if let Some(hit) = lift(p0, px as u32, py as u32) {
                                found = Some(hit);
                                break 'ring;
                            }
                        }
                    }
                }
                r += 1;
            }
            let Some((pp, ppt)) = found else { continue };
            let g_local = gt.poses[0][gp].to_rigid().inverse() * gpt;
            let p_local = pred_t0[pp].inverse().transform_point(&ppt);
            queries.push((gp, g_local, pp, p_local));
        }
        if !queries.is_empty() {
            let mut sum = 0.0;
            let mut count = 0usize;
            for f in 0..n {
                let pt = pred_part_transforms(pred, f);
                for (gp, gl, pp, pl) in &queries {
                    let g = gt.poses[f][*gp].to_rigid() * gl;
                    let p = Point3::from(pt[*pp].transform_point(pl).coords * s_hat);
                    sum += (g - p).norm();
                    count += 1;
                }
            }
            epe = Some(100.0 * sum / count as f64);
            epe_points = queries.len();
        }
    }

    // Rigid: the ground-truth base part against the predicted object pose.
    let gt_base: Vec<ObjectPose> = (0..n).map(|f| gt.poses[f][gt.base_part]).collect();
    let pr_base: Vec<ObjectPose> = (0..n).map(|f| pred.poses[f].pose).collect();
    let rigid = gauge_aligned_errors(&gt_base, &pr_base, pred.scale, s_hat);

    // Articulation.
    let tree = &pred.model.tree;
    let joints = gt
        .joints
        .iter()
        .map(|gj| {
            let child_name = &gt.part_names[gj.child];
            let by_name = pred
                .model
                .part_index(child_name)
                .and_then(|pi| tree.part_joint(pi));
            let (pj, matched_by) = match by_name {
                Some(j) => (Some(j), "child part name"),
                None => {
                    let gc =
                        transform_rigid(&gt.meshes[gj.child], &gt.poses[0][gj.child].to_rigid())
                            .bounds()
                            .center();
                    let t0 = pred_part_transforms(pred, 0);
                    let best = (0..tree.joints().len())
                        .filter(|&j| tree.joints()[j].kind.has_state())
                        .filter_map(|j| {
                            let mut b = agentstar_geom::Aabb::empty();
                            for (pi, part) in pred.model.parts.iter().enumerate() {
                                if tree.part_joint(pi) == Some(j) {
                                    b = b.union(
                                        &mesh_points(&part.mesh, |q| {
                                            Point3::from(t0[pi].transform_point(q).coords * s_hat)
                                        })
                                        .bounds(),
                                    );
                                }
                            }
                            (!b.is_empty()).then(|| (j, (b.center() - gc).norm()))
                        })
                        .min_by(|a, b| a.1.total_cmp(&b.1));
                    (best.map(|b| b.0), "nearest moving parts")
                }
            };
            let Some(pj) = pj else {
                return JointMetrics {
                    gt_joint: gj.name.clone(),
                    pred_joint: None,
                    matched_by: "unmatched",
                    revolute: gj.revolute,
                    axis_angle_rad: None,
                    axis_distance_m: None,
                    state_error: None,
                };
            };
            let jd = &tree.joints()[pj];
            // Axes in the first keyframe's camera.
            let gparent = gt.poses[0][gj.parent];
            let g_axis = gparent.rotation * gj.axis;
            let g_origin = gparent.rotation * gj.origin + gparent.translation;
            let GenPose {
                pose: pose0,
                states: states0,
            } = &pred.poses[0];
            let parent_acc = jd
                .parent
                .as_deref()
                .and_then(|p| tree.joint_index(p))
                .map(|pi| tree.joint_transforms(states0)[pi])
                .unwrap_or_else(agentstar_geom::pose::Rigid::identity);
            let p_axis = pose0.rotation * (parent_acc.rotation * jd.axis);
            let p_origin = Point3::from(
                pose0
                    .with_scale(pred.scale)
                    .transform_point(&(parent_acc * Point3::from(jd.origin)))
                    .coords
                    * s_hat,
            );
            let angular = jd.kind.is_angular();
            let pred_states: Vec<f64> = (0..n)
                .map(|f| {
                    let v = pred.poses[f].states[pj];
                    if angular {
                        v
                    } else {
                        v * pred.scale * s_hat
                    }
                })
                .collect();
            JointMetrics {
                gt_joint: gj.name.clone(),
                pred_joint: Some(jd.name.clone()),
                matched_by,
                revolute: gj.revolute,
                axis_angle_rad: Some(axis_angle_error(&p_axis, &g_axis)),
                axis_distance_m: gj
                    .revolute
                    .then(|| axis_line_distance(&p_origin.coords, &p_axis, &g_origin, &g_axis)),
                state_error: state_error(&pred_states, &gj.states[..n.min(gj.states.len())]),
            }
        })
        .collect();
    SequenceMetrics {
        frames: n,
        scale_alignment: s_hat,
        epe_cm: epe,
        epe_points,
        chamfer_cm: mean_cm(&cd_w),
        cd_moving_cm: mean_cm(&cd_m),
        cd_static_cm: mean_cm(&cd_s),
        cd_sq_whole_m2: mean_m2(&cd_w),
        cd_sq_moving_m2: mean_m2(&cd_m),
        cd_sq_static_m2: mean_m2(&cd_s),
        rigid,
        joints,
    }
}
