//! Placing an object model in a camera: forward kinematics per part, composed with the
//! object pose, as renderer instances.

use crate::raster::{Affine, Instance};
use agentstar_geom::pose::{Rigid, Similarity};
use agentstar_geom::ObjectModel;

/// The model's parts placed in one camera for one generalised pose.
#[derive(Debug, Clone)]
pub struct PosedModel<'a> {
    pub instances: Vec<Instance<'a>>,
}

impl<'a> PosedModel<'a> {
    /// `states` in internal units (radians, canonical units); `camera_from_object` is
    /// `p_cam = s · R · p_canon + t`.
    pub fn new(model: &'a ObjectModel, states: &[f64], camera_from_object: &Similarity) -> Self {
        let mut instances = Vec::with_capacity(model.parts.len());
        fill_instances(model, states, camera_from_object, &mut instances);
        PosedModel { instances }
    }
}

/// Fills `out` (cleared first) with one instance per part. Allocates for forward
/// kinematics; search loops use [`InstanceBuilder`], which does not.
pub fn fill_instances<'a>(
    model: &'a ObjectModel,
    states: &[f64],
    camera_from_object: &Similarity,
    out: &mut Vec<Instance<'a>>,
) {
    InstanceBuilder::default().build(model, states, camera_from_object, out);
}

/// Each part's visible pixels (the nearest surface, as the full renderer draws part ids)
/// summed over `views` (a camera, the object's pose in it and the joint states, internal
/// units), indexed like `model.parts`: what a shape edit reads to hold the part most in
/// view in place ([`agentstar_geom::held_part`]).
pub fn visible_part_pixels<'v>(
    model: &ObjectModel,
    views: impl IntoIterator<Item = (&'v agentstar_geom::PinholeCamera, Similarity, &'v [f64])>,
) -> Vec<u64> {
    let mut counts = vec![0u64; model.parts.len()];
    let mut renderer = crate::full::FullRenderer::default();
    let mut instances = Vec::new();
    let mut builder = InstanceBuilder::default();
    for (camera, pose, states) in views {
        builder.build(model, states, &pose, &mut instances);
        let seen = renderer
            .render(camera, &instances)
            .part_pixels(counts.len());
        for (c, n) in counts.iter_mut().zip(seen) {
            *c += n;
        }
    }
    counts
}

/// Reusable forward-kinematics buffers for placing a model many times without allocating.
#[derive(Debug, Default, Clone)]
pub struct InstanceBuilder {
    joints: Vec<Rigid>,
    parts: Vec<Rigid>,
}

impl InstanceBuilder {
    pub fn build<'a>(
        &mut self,
        model: &'a ObjectModel,
        states: &[f64],
        camera_from_object: &Similarity,
        out: &mut Vec<Instance<'a>>,
    ) {
        model
            .tree
            .part_transforms_into(states, &mut self.joints, &mut self.parts);
        place(model, &self.parts, camera_from_object, out);
    }
}

fn place<'a>(
    model: &'a ObjectModel,
    transforms: &[Rigid],
    camera_from_object: &Similarity,
    out: &mut Vec<Instance<'a>>,
) {
    out.clear();
    for (i, (part, object_from_part)) in model.parts.iter().zip(transforms).enumerate() {
        out.push(Instance {
            mesh: &part.mesh,
            bounds: part.bounds,
            camera_from_mesh: Affine::camera_from_part(camera_from_object, object_from_part),
            edges: part.edges.as_deref().map(|e| e.as_slice()),
            open_edges: part.open_edges.as_deref().map(|e| e.as_slice()),
            planes: part.planes.as_deref().map(|q| q.as_slice()),
            part_id: i as u16,
        });
    }
}
