//! The colour of the model's surface at each pixel of a full render: the part's texture and
//! vertex colours where it has them, else its colour.
//!
//! Each covered pixel's surface point is the ray through its centre at its planar depth,
//! and its barycentric coordinates in the visible triangle are computed in the camera
//! frame, so texture coordinates and vertex colours are interpolated perspective-correctly
//! (exactly, not by screen-space weights); textures are sampled bilinearly
//! ([`agentstar_geom::Texture::sample`]).

use crate::full::{RenderBuffers, NO_PART};
use crate::raster::Instance;
use agentstar_geom::{ObjectModel, PinholeCamera};

/// The barycentric coordinates of `p` in the triangle `a, b, c` (camera frame), clamped to
/// the triangle (a pixel centre on its edge may fall a rounding error outside).
pub fn barycentric(p: [f64; 3], a: [f64; 3], b: [f64; 3], c: [f64; 3]) -> [f32; 3] {
    let sub = |x: [f64; 3], y: [f64; 3]| [x[0] - y[0], x[1] - y[1], x[2] - y[2]];
    let dot = |x: [f64; 3], y: [f64; 3]| x[0] * y[0] + x[1] * y[1] + x[2] * y[2];
    let (v0, v1, v2) = (sub(b, a), sub(c, a), sub(p, a));
    let (d00, d01, d11) = (dot(v0, v0), dot(v0, v1), dot(v1, v1));
    let (d20, d21) = (dot(v2, v0), dot(v2, v1));
    let denom = d00 * d11 - d01 * d01;
    if !(denom.is_finite() && denom.abs() > 0.0) {
        return [1.0 / 3.0; 3];
    }
    let v = ((d11 * d20 - d01 * d21) / denom).clamp(0.0, 1.0);
    let w = ((d00 * d21 - d01 * d20) / denom).clamp(0.0, 1.0);
    let (v, w) = if v + w > 1.0 {
        (v / (v + w), w / (v + w))
    } else {
        (v, w)
    };
    [(1.0 - v - w) as f32, v as f32, w as f32]
}

/// Per pixel (row-major), the surface colour of the part seen there; `None` where nothing
/// is. `instances` are the ones `buffers` was rendered from (their `part_id` indexes
/// `model.parts`, as [`crate::PosedModel`] places them).
pub fn surface_colors(
    model: &ObjectModel,
    instances: &[Instance<'_>],
    camera: &PinholeCamera,
    buffers: &RenderBuffers,
) -> Vec<Option<[f32; 3]>> {
    let mut by_part: Vec<Option<&Instance<'_>>> = vec![None; model.parts.len()];
    for inst in instances {
        if let Some(slot) = by_part.get_mut(usize::from(inst.part_id)) {
            *slot = Some(inst);
        }
    }
    let w = buffers.width as usize;
    let mut out = vec![None; buffers.part.len()];
    for (k, slot) in out.iter_mut().enumerate() {
        let p = buffers.part[k];
        if p == NO_PART {
            continue;
        }
        let Some(part) = model.parts.get(usize::from(p)) else {
            *slot = Some([0.7; 3]);
            continue;
        };
        *slot = Some(match (&part.surface, by_part[usize::from(p)]) {
            (Some(surface), Some(inst)) => {
                let t = buffers.triangle[k] as usize;
                match inst.mesh.triangles.get(t) {
                    Some(tri) => {
                        let corner = |i: u32| {
                            inst.camera_from_mesh
                                .apply(&inst.mesh.positions[i as usize])
                        };
                        let z = f64::from(buffers.depth[k]);
                        let (x, y) = ((k % w) as f64 + 0.5, (k / w) as f64 + 0.5);
                        let hit = [
                            (x - camera.cx) / camera.fx * z,
                            (y - camera.cy) / camera.fy * z,
                            z,
                        ];
                        let bary = barycentric(hit, corner(tri[0]), corner(tri[1]), corner(tri[2]));
                        surface.color_at(t, bary)
                    }
                    None => part.color,
                }
            }
            _ => part.color,
        });
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn barycentric_coordinates_rebuild_the_point() {
        let (a, b, c) = ([0.0, 0.0, 1.0], [1.0, 0.0, 2.0], [0.0, 1.0, 3.0]);
        let w = [0.2, 0.3, 0.5];
        let p = [0, 1, 2].map(|i| w[0] * a[i] + w[1] * b[i] + w[2] * c[i]);
        let got = barycentric(p, a, b, c);
        for i in 0..3 {
            assert!((f64::from(got[i]) - w[i]).abs() < 1e-6, "{got:?}");
        }
        // Outside: clamped onto the triangle, still summing to one.
        let out = barycentric([2.0, 2.0, 1.0], a, b, c);
        assert!((out.iter().sum::<f32>() - 1.0).abs() < 1e-6 && out.iter().all(|&v| v >= 0.0));
    }
}
