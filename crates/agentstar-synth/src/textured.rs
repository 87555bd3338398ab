//! The true model as a mesh file would carry it: the parts of a rigid object merged at rest
//! into one mesh, its appearance (a print, a checker, or its part colours) painted into a
//! per-triangle texture atlas ([`agentstar_geom::atlas`]) as a camera shows it under full
//! light (display values, gamma 2.2, as the captures' frames are written) — the textured
//! GLB or OBJ + MTL a scan or a CAD export gives a user; and the same mesh uncoloured.

use crate::objects::Appearance;
use crate::{albedo, srgb, to_u8, SynthError};
use agentstar_geom::{AtlasLayout, ObjectModel, Part, Texture};
use std::sync::Arc;

/// The atlas's width in texels (its height follows from the layout).
const ATLAS_WIDTH: u32 = 2048;

/// `model`'s parts merged at rest into one part of one colour (the mean of the parts'
/// colours weighted by area): the uncoloured mesh. Refused for a model with joints.
pub fn plain_mesh_model(model: &ObjectModel) -> Result<ObjectModel, SynthError> {
    let (merged, _) = merge(model)?;
    let (mut sum, mut total) = ([0.0f64; 3], 0.0);
    for p in &model.parts {
        let a = p.mesh.area();
        for k in 0..3 {
            sum[k] += a * f64::from(p.color[k]);
        }
        total += a;
    }
    let color = sum.map(|s| (s / total.max(f64::MIN_POSITIVE)) as f32);
    Ok(ObjectModel {
        tree: agentstar_geom::KinematicTree::rigid(1),
        parts: vec![Part::new("object", merged, color)],
    })
}

/// `model` (rigid) as one part textured with its `appearance` at `texels_per_unit` texels
/// per model unit.
pub fn textured_model(
    model: &ObjectModel,
    appearance: Appearance,
    texels_per_unit: f64,
) -> Result<ObjectModel, SynthError> {
    let geom = |e: agentstar_geom::GeomError| SynthError::Config(e.to_string());
    let (merged, owner) = merge(model)?;
    let one = ObjectModel {
        tree: agentstar_geom::KinematicTree::rigid(1),
        parts: vec![Part::new("object", merged, [1.0, 1.0, 1.0])],
    };
    let layout = AtlasLayout::new(&one, texels_per_unit, ATLAS_WIDTH).map_err(geom)?;
    let (w, h) = (layout.width, layout.height);
    if h > 2 * ATLAS_WIDTH {
        return Err(SynthError::Config(format!(
            "the model's texture atlas at {texels_per_unit} texels per unit is {w}×{h}; ask for fewer texels per unit"
        )));
    }
    let mut rgb = vec![0u8; 3 * (w as usize) * (h as usize)];
    let mesh = &one.parts[0].mesh;
    for (t, patch) in layout.patches[0].iter().enumerate() {
        let [a, b, c] = mesh.triangle(t);
        let part = owner[t];
        for y in patch.y0..patch.y0 + patch.height {
            for x in patch.x0..patch.x0 + patch.width {
                let [u, v, s] = patch.texel_barycentric(x, y);
                let p = agentstar_geom::Point3::from(a.coords * u + b.coords * v + c.coords * s);
                let colour = srgb(albedo(appearance, part, &p, model.parts[part].color));
                let k = 3 * (y as usize * w as usize + x as usize);
                for (i, v) in colour.iter().enumerate() {
                    rgb[k + i] = to_u8(*v);
                }
            }
        }
    }
    let texture = Arc::new(Texture::new("print", w, h, rgb).map_err(geom)?);
    agentstar_geom::with_atlas(&one, &layout, texture).map_err(geom)
}

/// The parts of a rigid `model` in one mesh, and each triangle's part.
fn merge(model: &ObjectModel) -> Result<(agentstar_geom::TriMesh, Vec<usize>), SynthError> {
    if !model.tree.joints().is_empty() {
        return Err(SynthError::Config(
            "a model with joints is not one mesh: its parts move".into(),
        ));
    }
    let mut merged = agentstar_geom::TriMesh::new(vec![], vec![]);
    let mut owner = Vec::new();
    for (k, p) in model.parts.iter().enumerate() {
        merged.append(&p.mesh);
        owner.extend(std::iter::repeat_n(k, p.mesh.triangles.len()));
    }
    Ok((merged, owner))
}
