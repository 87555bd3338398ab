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
        for (s, c) in sum.iter_mut().zip(p.color) {
            *s += a * f64::from(c);
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::objects::ObjectSpec;
    use agentstar_geom::Point3;

    /// A smooth paint: the texture at a triangle's centroid is the paint there.
    fn ramp(_part: usize, p: &Point3) -> [f64; 3] {
        [
            0.2 + 0.3 * (p.x + 0.5),
            0.2 + 0.3 * (p.y + 0.5),
            0.2 + 0.3 * (p.z + 0.5),
        ]
    }

    #[test]
    fn the_texture_holds_the_print_as_a_camera_shows_it_and_joints_are_refused() {
        let spec = ObjectSpec::resolve("labelcan").expect("labelcan");
        let model = crate::build_object(&spec).expect("model");
        let textured = textured_model(&model, Appearance::Printed(ramp), 64.0).expect("texture");
        assert_eq!(textured.parts.len(), 1);
        let part = &textured.parts[0];
        let triangles: usize = model.parts.iter().map(|p| p.mesh.triangles.len()).sum();
        assert_eq!(part.mesh.triangles.len(), triangles);
        let mut worst = 0.0f64;
        for t in 0..part.mesh.triangles.len() {
            let [a, b, c] = part.mesh.triangle(t);
            let centroid = Point3::from((a.coords + b.coords + c.coords) / 3.0);
            let want = srgb(ramp(0, &centroid));
            let got = part.color_at(t, [1.0 / 3.0; 3]);
            for k in 0..3 {
                worst = worst.max((f64::from(got[k]) - want[k]).abs());
            }
        }
        assert!(worst < 4.0 / 255.0, "{worst}");
        // The uncoloured mesh: one part, one colour, the same triangles.
        let plain = plain_mesh_model(&model).expect("plain");
        assert_eq!(plain.parts.len(), 1);
        assert!(plain.parts[0].surface.is_none());
        assert_eq!(plain.parts[0].mesh.triangles.len(), triangles);
        // A model with joints is no one mesh.
        let laptop =
            crate::build_object(&ObjectSpec::resolve("laptop").expect("laptop")).expect("model");
        assert!(textured_model(&laptop, Appearance::Plain, 64.0).is_err());
        assert!(plain_mesh_model(&laptop).is_err());
    }
}
