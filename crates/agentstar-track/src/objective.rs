//! One frame's search problem: the model, the camera, the target mask (hands excluded),
//! the base generalised pose and its frozen pivot, and how a search vector becomes a
//! candidate pose and a score.

use crate::space::{Dof, SearchSpace};
use crate::update::{
    apply_camera_order, apply_object_rotation, pivot_in_camera, rotation_vector_deg, CameraOrder,
    GenPose,
};
use agentstar_geom::{ObjectModel, PinholeCamera, Point3};
use agentstar_render::raster::Instance;
use agentstar_render::scene::InstanceBuilder;
use agentstar_render::score::{combined_score, depth_score};
use agentstar_render::{
    render_full, DepthObservation, PosedModel, ScoreTarget, SilhouetteRenderer,
};

/// Score of a candidate that would put the object behind the camera.
pub const BEHIND_CAMERA: f64 = -1e18;

#[derive(Debug, Clone)]
pub struct FrameProblem<'a> {
    pub model: &'a ObjectModel,
    pub camera: PinholeCamera,
    pub target: &'a ScoreTarget,
    pub depth: Option<&'a DepthObservation>,
    pub depth_weight: f64,
    pub scale: f64,
    pub base: GenPose,
    /// Canonical pivot (bounding-box centre of the posed parts at the base states), frozen.
    pub pivot: Point3,
    /// The same frame at half the resolution ([`FrameProblem::with_coarse`]), for the wide
    /// first passes of a local refinement; `None`: every pass at full resolution.
    pub coarse: Option<(PinholeCamera, &'a ScoreTarget)>,
    /// An axis of the model (canonical frame) whose turn the silhouette cannot measure (a
    /// round outline's, [`crate::axis::outline_axis`]): the CMA-ES end of a local
    /// refinement keeps the base's turn about it ([`crate::axis::SymmetryAxis::without_twist`]).
    /// `None`: every turn is searched.
    pub held_axis: Option<crate::axis::SymmetryAxis>,
}

/// The figures of one candidate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CandidateScore {
    /// Visible-region IoU (raw IoU without a hand mask); 0 when nothing is visible.
    pub gate: f64,
    pub iou_raw: f64,
    pub iou_visible: Option<f64>,
    /// IoU with the observed mask's boundary band also excluded, when the target scores a
    /// band ([`ScoreTarget::with_band`]); reported, never searched on.
    pub iou_band: Option<f64>,
    /// Depth error in canonical units, when depth is scored.
    pub depth_canon: Option<f64>,
    /// `gate − w · min(depth_canon, 1)`, or [`BEHIND_CAMERA`].
    pub combined: f64,
}

impl<'a> FrameProblem<'a> {
    pub fn new(
        model: &'a ObjectModel,
        camera: PinholeCamera,
        target: &'a ScoreTarget,
        scale: f64,
        base: GenPose,
    ) -> Self {
        let pivot = model.pivot(&base.states);
        FrameProblem {
            model,
            camera,
            target,
            depth: None,
            depth_weight: 0.0,
            scale,
            base,
            pivot,
            coarse: None,
            held_axis: None,
        }
    }

    /// This problem with `axis` held ([`FrameProblem::held_axis`]).
    pub fn with_held_axis(mut self, axis: Option<crate::axis::SymmetryAxis>) -> Self {
        self.held_axis = axis;
        self
    }

    /// This problem with `halved` (the target at half the resolution,
    /// [`ScoreTarget::halved`]) for its coarse passes; ignored when depth is scored.
    pub fn with_coarse(mut self, halved: &'a ScoreTarget) -> Self {
        self.coarse = Some((self.camera.halved(), halved));
        self
    }

    /// This problem at half the resolution, when it has one and scores no depth.
    pub fn coarsened(&self) -> Option<FrameProblem<'a>> {
        let (camera, target) = self.coarse?;
        if self.depth.is_some() && self.depth_weight > 0.0 {
            return None;
        }
        Some(FrameProblem {
            camera,
            target,
            coarse: None,
            ..self.clone()
        })
    }

    /// The candidate a search vector stands for: pose DOFs are increments on the base pose
    /// (camera-frame orders about the pivot, then object-frame rotation vectors), joint DOFs
    /// are absolute states clamped to their limits; unnamed joints keep the base state.
    pub fn candidate(&self, space: &SearchSpace, x: &[f64]) -> GenPose {
        let mut order = CameraOrder::default();
        let mut rotvec = [0.0; 3];
        let mut states = self.base.states.clone();
        let tree = &self.model.tree;
        for (r, &v) in space.ranges.iter().zip(x) {
            match r.dof {
                Dof::Roll => order.roll_deg = v,
                Dof::Yaw => order.yaw_deg = v,
                Dof::Pitch => order.pitch_deg = v,
                Dof::Dpx => order.dpx = v,
                Dof::Dpy => order.dpy = v,
                Dof::Tz => order.tz = v,
                Dof::Rx => rotvec[0] = v,
                Dof::Ry => rotvec[1] = v,
                Dof::Rz => rotvec[2] = v,
                Dof::Joint(j) => states[j] = tree.joints()[j].to_internal(v),
            }
        }
        tree.clamp_states(&mut states);
        let mut pose = apply_camera_order(
            &self.base.pose,
            self.scale,
            &self.pivot,
            &self.camera,
            &order,
        );
        if rotvec != [0.0; 3] {
            pose =
                apply_object_rotation(&pose, self.scale, &self.pivot, &rotation_vector_deg(rotvec));
        }
        pose.rotation.renormalize();
        GenPose { pose, states }
    }

    /// The search vector of the base pose: zero increments and the base joint states.
    pub fn start_vector(&self, space: &SearchSpace) -> Vec<f64> {
        space
            .ranges
            .iter()
            .map(|r| match r.dof {
                Dof::Joint(j) => self.model.tree.joints()[j]
                    .to_interface(self.base.states[j])
                    .clamp(r.lo, r.hi),
                _ => 0.0f64.clamp(r.lo, r.hi),
            })
            .collect()
    }

    pub fn evaluator(&self) -> Evaluator<'_, 'a> {
        Evaluator {
            problem: self,
            renderer: pooled_renderer(self.camera.width, self.camera.height),
            builder: InstanceBuilder::default(),
            instances: Vec::new(),
        }
    }
}

/// The band IoU of `pose` against `banded`, a target that scores a boundary band
/// ([`ScoreTarget::with_band`]): the figure the IoU gate reads; the visible IoU when the
/// target has no band. One render, not for search loops.
pub fn band_iou(
    model: &ObjectModel,
    camera: PinholeCamera,
    banded: &ScoreTarget,
    scale: f64,
    pose: &GenPose,
) -> f64 {
    let score = FrameProblem::new(model, camera, banded, scale, pose.clone())
        .evaluator()
        .score(pose);
    score.iou_band.unwrap_or(score.gate)
}

/// Per-thread scoring state (renderer and buffers reused across candidates).
pub struct Evaluator<'p, 'a> {
    problem: &'p FrameProblem<'a>,
    renderer: SilhouetteRenderer,
    builder: InstanceBuilder,
    instances: Vec<Instance<'a>>,
}

/// Renderers no evaluator holds, per thread: searches make evaluators by the thousand (one
/// per refinement, per placed hypothesis), and a fresh 640×480 renderer is a zeroed
/// allocation that the allocator may hand back to the system and fault in again.
const RENDERER_POOL: usize = 8;

thread_local! {
    static RENDERERS: std::cell::RefCell<Vec<SilhouetteRenderer>> =
        const { std::cell::RefCell::new(Vec::new()) };
}

/// A renderer of this size from this thread's pool (a render clears what its last one
/// drew), or a new one; give it back with [`return_renderer`]. By size: local searches
/// alternate full- and half-resolution problems, and a renderer of the other size would be
/// reallocated on every render.
pub(crate) fn pooled_renderer(width: u32, height: u32) -> SilhouetteRenderer {
    RENDERERS
        .with_borrow_mut(|pool| {
            let k = pool
                .iter()
                .rposition(|r| (r.mask().width(), r.mask().height()) == (width, height))?;
            Some(pool.swap_remove(k))
        })
        .unwrap_or_else(|| SilhouetteRenderer::new(width, height))
}

/// Puts a renderer back in this thread's pool (up to [`RENDERER_POOL`] are kept).
pub(crate) fn return_renderer(renderer: SilhouetteRenderer) {
    RENDERERS.with_borrow_mut(|pool| {
        if pool.len() < RENDERER_POOL {
            pool.push(renderer);
        }
    });
}

impl Drop for Evaluator<'_, '_> {
    fn drop(&mut self) {
        return_renderer(std::mem::replace(
            &mut self.renderer,
            SilhouetteRenderer::new(0, 0),
        ));
    }
}

impl Evaluator<'_, '_> {
    /// Every figure of a candidate (renders depth too when the problem scores depth).
    pub fn score(&mut self, g: &GenPose) -> CandidateScore {
        let p = self.problem;
        let sim = g.pose.with_scale(p.scale);
        // The frozen pivot, as in `combined`: the same test in both, and no pass over every
        // vertex per candidate.
        if pivot_in_camera(&g.pose, p.scale, &p.pivot).z <= 0.0 {
            return CandidateScore {
                gate: 0.0,
                iou_raw: 0.0,
                iou_visible: None,
                iou_band: None,
                depth_canon: None,
                combined: BEHIND_CAMERA,
            };
        }
        self.builder
            .build(p.model, &g.states, &sim, &mut self.instances);
        let s = p
            .target
            .score(self.renderer.render(&p.camera, &self.instances));
        let depth_canon = match p.depth {
            Some(obs) if p.depth_weight > 0.0 => {
                let buffers = render_full(
                    &p.camera,
                    &PosedModel::new(p.model, &g.states, &sim).instances,
                );
                // A candidate with no scorable depth pixels takes the full penalty.
                Some(
                    depth_score(&buffers, obs, p.target, p.scale, 0.1)
                        .ok()
                        .flatten()
                        .map_or(1.0, |d| d.mae_canon),
                )
            }
            _ => None,
        };
        let combined = match depth_canon {
            Some(d) => s.gate() - p.depth_weight * d.min(1.0),
            None => combined_score(s.gate(), None, 0.0),
        };
        CandidateScore {
            gate: s.gate(),
            iou_raw: s.iou_raw,
            iou_visible: s.iou_visible,
            iou_band: s.iou_band,
            depth_canon,
            combined,
        }
    }

    /// The combined score with the silhouette's coverage measured at sub-pixel precision
    /// along rows ([`ScoreTarget::soft_gate`]), for a fine local search; the combined score
    /// itself when the problem scores depth.
    pub fn soft_combined(&mut self, g: &GenPose) -> f64 {
        if let Err(known) = self.silhouette_instances(g) {
            return known;
        }
        let p = self.problem;
        p.target
            .soft_gate(self.renderer.render_spans(&p.camera, &self.instances))
    }

    /// `g`'s instances built for a silhouette score, or `Err` with the score where none is
    /// needed: the whole score when the problem scores depth, [`BEHIND_CAMERA`] behind it.
    fn silhouette_instances(&mut self, g: &GenPose) -> Result<(), f64> {
        let p = self.problem;
        if p.depth.is_some() && p.depth_weight > 0.0 {
            return Err(self.score(g).combined);
        }
        // The frozen pivot, as in `score`.
        if pivot_in_camera(&g.pose, p.scale, &p.pivot).z <= 0.0 {
            return Err(BEHIND_CAMERA);
        }
        self.builder.build(
            p.model,
            &g.states,
            &g.pose.with_scale(p.scale),
            &mut self.instances,
        );
        Ok(())
    }

    /// The combined score only, for search loops (no depth: one silhouette and popcounts).
    pub fn combined(&mut self, g: &GenPose) -> f64 {
        if let Err(known) = self.silhouette_instances(g) {
            return known;
        }
        let p = self.problem;
        self.renderer.render(&p.camera, &self.instances);
        p.target
            .gate_rows(self.renderer.mask(), self.renderer.rows())
    }
}
