//! A per-triangle texture atlas: every triangle of every part gets its own rectangle of
//! texels, laid out from the tessellation alone, so any model (a scene script's primitives
//! with no texture coordinates, a scanned mesh) can carry a baked texture.
//!
//! Each triangle is laid flat with its longest edge along the atlas's x axis and its third
//! corner above it (the triangle's own shape, so texels are square on the surface: the
//! resolution is the same in every direction), scaled by one density for the whole model
//! (`texels_per_unit`, texels per model unit of length), and given a gutter of one texel on
//! every side. Texels of the rectangle outside the triangle stand for the nearest point of
//! the triangle, so bilinear samples at its edges never read another triangle's colours.
//! Rectangles are packed in shelves (tallest first) into an atlas of a fixed width.
//!
//! The layout is a function of the tessellation, the density and the width: a bake stores
//! the density and the width and a [`tessellation_fingerprint`], and whoever loads it lays
//! the atlas out again, which is only valid on the same tessellation (the fingerprint says
//! whether it is). Both read each triangle by its corners' positions, not by its index or
//! its vertices' indices: a script's booleans may return the same triangles in another
//! order from one build to the next (measured on the printed mug: three fingerprints in four
//! builds of one script when they read indices), and the layout follows the triangles.

use crate::appearance::{Material, SurfaceAppearance, Texture, WrapMode};
use crate::model::ObjectModel;
use crate::{GeomError, Point3, Result};
use std::sync::Arc;

/// Texels of gutter around each triangle's rectangle.
pub const GUTTER_TEXELS: u32 = 1;

/// The version of the layout rule; a bake made under another is stale.
pub const ATLAS_LAYOUT_VERSION: u32 = 1;

/// One triangle's rectangle in the atlas and where its corners lie there.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Patch {
    /// Top-left texel of the rectangle (gutter included).
    pub x0: u32,
    pub y0: u32,
    /// Size in texels, gutter included.
    pub width: u32,
    pub height: u32,
    /// The triangle's corners (in the mesh's corner order) in atlas texel coordinates
    /// (texel `i` spans `[i, i + 1)`).
    pub corners: [[f64; 2]; 3],
}

impl Patch {
    /// The barycentric coordinates of the point of the triangle nearest the texel centre
    /// `(x + ½, y + ½)` (clamped onto the triangle where the texel lies outside it).
    pub fn texel_barycentric(&self, x: u32, y: u32) -> [f64; 3] {
        let p = [f64::from(x) + 0.5, f64::from(y) + 0.5];
        barycentric_2d(p, self.corners)
    }
}

/// The point of triangle `t` nearest `p`, as barycentric coordinates.
fn barycentric_2d(p: [f64; 2], t: [[f64; 2]; 3]) -> [f64; 3] {
    let [a, b, c] = t;
    let v0 = [b[0] - a[0], b[1] - a[1]];
    let v1 = [c[0] - a[0], c[1] - a[1]];
    let v2 = [p[0] - a[0], p[1] - a[1]];
    let det = v0[0] * v1[1] - v1[0] * v0[1];
    if !(det.is_finite() && det.abs() > 1e-12) {
        return [1.0 / 3.0; 3];
    }
    let v = (v2[0] * v1[1] - v1[0] * v2[1]) / det;
    let w = (v0[0] * v2[1] - v2[0] * v0[1]) / det;
    let u = 1.0 - v - w;
    if u >= 0.0 && v >= 0.0 && w >= 0.0 {
        return [u, v, w];
    }
    // Outside: the nearest point on the nearest edge.
    let edge = |a: [f64; 2], b: [f64; 2]| -> (f64, f64) {
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let s = if len2 > 0.0 {
            (((p[0] - a[0]) * d[0] + (p[1] - a[1]) * d[1]) / len2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let q = [a[0] + s * d[0], a[1] + s * d[1]];
        ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2), s)
    };
    let (dab, sab) = edge(a, b);
    let (dbc, sbc) = edge(b, c);
    let (dca, sca) = edge(c, a);
    if dab <= dbc && dab <= dca {
        [1.0 - sab, sab, 0.0]
    } else if dbc <= dca {
        [0.0, 1.0 - sbc, sbc]
    } else {
        [sca, 0.0, 1.0 - sca]
    }
}

/// Where every triangle of a model lies in the atlas.
#[derive(Debug, Clone, PartialEq)]
pub struct AtlasLayout {
    pub width: u32,
    pub height: u32,
    pub texels_per_unit: f64,
    /// Per part (as `model.parts`), per triangle.
    pub patches: Vec<Vec<Patch>>,
}

fn invalid(reason: String) -> GeomError {
    GeomError::InvalidArgument {
        primitive: "texture atlas".into(),
        reason,
    }
}

/// A triangle's corners as bits (`-0.0` read as `0.0`), starting from its smallest corner
/// (its winding kept), and that corner's index: the same key however a mesh numbers its
/// vertices or orders its triangles.
fn triangle_key(t: [Point3; 3]) -> ([u64; 9], usize) {
    let bits = |p: &Point3| {
        [
            (p.x + 0.0).to_bits(),
            (p.y + 0.0).to_bits(),
            (p.z + 0.0).to_bits(),
        ]
    };
    let c = [bits(&t[0]), bits(&t[1]), bits(&t[2])];
    let r = (0..3).min_by_key(|&i| c[i]).unwrap_or(0);
    let mut key = [0u64; 9];
    for m in 0..3 {
        key[3 * m..3 * m + 3].copy_from_slice(&c[(r + m) % 3]);
    }
    (key, r)
}

/// A triangle laid flat: the corners' 2-D coordinates in model units (longest edge on the
/// x axis from the origin, the third corner at y ≥ 0) and the bounding size.
fn flatten(t: [Point3; 3]) -> ([[f64; 2]; 3], [f64; 2]) {
    let len = |i: usize| (t[(i + 1) % 3] - t[i]).norm();
    let lens = [len(0), len(1), len(2)];
    let mut i = 0;
    for k in 1..3 {
        if lens[k] > lens[i] {
            i = k;
        }
    }
    let (j, k) = ((i + 1) % 3, (i + 2) % 3);
    let l = lens[i];
    let mut out = [[0.0; 2]; 3];
    if !(l.is_finite() && l > 0.0) {
        return (out, [0.0, 0.0]);
    }
    let e = (t[j] - t[i]) / l;
    let d = t[k] - t[i];
    let along = d.dot(&e).clamp(0.0, l);
    let across = (d - e * d.dot(&e)).norm();
    let across = if across.is_finite() { across } else { 0.0 };
    out[j] = [l, 0.0];
    out[k] = [along, across];
    (out, [l, across])
}

impl AtlasLayout {
    /// The layout of `model`'s triangles at `texels_per_unit` in an atlas `width` texels
    /// wide; refused when a triangle's rectangle is wider than the atlas or the density is
    /// not a positive number.
    pub fn new(model: &ObjectModel, texels_per_unit: f64, width: u32) -> Result<AtlasLayout> {
        if !(texels_per_unit.is_finite() && texels_per_unit > 0.0) {
            return Err(invalid(format!(
                "texels per unit must be a positive number, not {texels_per_unit}"
            )));
        }
        if width == 0 {
            return Err(invalid("an atlas 0 texels wide".into()));
        }
        // Every triangle's flat shape and rectangle size.
        struct Item {
            part: usize,
            tri: usize,
            key: [u64; 9],
            flat: [[f64; 2]; 3],
            w: u32,
            h: u32,
        }
        let mut items = Vec::new();
        for (p, part) in model.parts.iter().enumerate() {
            for t in 0..part.mesh.triangles.len() {
                // Laid flat from its smallest corner, so that the same triangle lies the same
                // way whatever its corners' order in the mesh.
                let tri = part.mesh.triangle(t);
                let (key, r) = triangle_key(tri);
                let (rotated, size) = flatten([tri[r], tri[(r + 1) % 3], tri[(r + 2) % 3]]);
                let mut flat = [[0.0; 2]; 3];
                for (m, c) in rotated.into_iter().enumerate() {
                    flat[(r + m) % 3] = c;
                }
                let texels = |v: f64| -> Result<u32> {
                    let n = (v * texels_per_unit).ceil().max(1.0);
                    if n > f64::from(width) {
                        return Err(invalid(format!(
                            "part `{}` triangle {t} needs {n} texels across at {texels_per_unit} texels per unit, more than the atlas's width {width}",
                            part.name
                        )));
                    }
                    Ok(n as u32 + 2 * GUTTER_TEXELS)
                };
                let (w, h) = (texels(size[0])?, texels(size[1])?);
                if w > width {
                    return Err(invalid(format!(
                        "part `{}` triangle {t}: a rectangle of {w} texels in an atlas {width} wide",
                        part.name
                    )));
                }
                items.push(Item {
                    part: p,
                    tri: t,
                    key,
                    flat,
                    w,
                    h,
                });
            }
        }
        // Shelves, tallest first (ties by part, then by the triangles' corners: the same
        // order however the mesh orders its triangles).
        let mut order: Vec<usize> = (0..items.len()).collect();
        order.sort_by(|&a, &b| {
            let (x, y) = (&items[a], &items[b]);
            y.h.cmp(&x.h)
                .then(x.part.cmp(&y.part))
                .then(x.key.cmp(&y.key))
                .then(a.cmp(&b))
        });
        let mut patches: Vec<Vec<Patch>> = model
            .parts
            .iter()
            .map(|p| {
                vec![
                    Patch {
                        x0: 0,
                        y0: 0,
                        width: 0,
                        height: 0,
                        corners: [[0.0; 2]; 3],
                    };
                    p.mesh.triangles.len()
                ]
            })
            .collect();
        let (mut x, mut y, mut shelf) = (0u32, 0u32, 0u32);
        for k in order {
            let it = &items[k];
            if x + it.w > width {
                y = y.saturating_add(shelf);
                x = 0;
                shelf = 0;
            }
            let origin = [
                f64::from(x + GUTTER_TEXELS),
                f64::from(y.saturating_add(GUTTER_TEXELS)),
            ];
            let corners = it.flat.map(|c| {
                [
                    origin[0] + c[0] * texels_per_unit,
                    origin[1] + c[1] * texels_per_unit,
                ]
            });
            patches[it.part][it.tri] = Patch {
                x0: x,
                y0: y,
                width: it.w,
                height: it.h,
                corners,
            };
            x += it.w;
            shelf = shelf.max(it.h);
        }
        let height = y.saturating_add(shelf).max(1);
        Ok(AtlasLayout {
            width,
            height,
            texels_per_unit,
            patches,
        })
    }

    /// Texels in the atlas.
    pub fn texel_count(&self) -> usize {
        self.width as usize * self.height as usize
    }

    /// Every part's surface appearance reading `atlas` (which must be this layout's size):
    /// one material whose texture is the atlas, texture coordinates at each triangle's
    /// corners in its rectangle.
    pub fn surfaces(&self, atlas: Arc<Texture>) -> Result<Vec<SurfaceAppearance>> {
        if (atlas.width(), atlas.height()) != (self.width, self.height) {
            return Err(invalid(format!(
                "an atlas image of {}×{} texels for a layout of {}×{}",
                atlas.width(),
                atlas.height(),
                self.width,
                self.height
            )));
        }
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        self.patches
            .iter()
            .map(|patches| {
                let uv = patches
                    .iter()
                    .map(|p| p.corners.map(|c| [(c[0] / w) as f32, (c[1] / h) as f32]))
                    .collect();
                SurfaceAppearance::new(
                    vec![Material {
                        name: "baked".into(),
                        color: [1.0; 3],
                        texture: Some(atlas.clone()),
                    }],
                    vec![0; patches.len()],
                    Some(uv),
                    None,
                )
            })
            .collect()
    }
}

/// `model` with every part's appearance replaced by the atlas `atlas` laid out by `layout`
/// (which must be `model`'s layout).
pub fn with_atlas(
    model: &ObjectModel,
    layout: &AtlasLayout,
    atlas: Arc<Texture>,
) -> Result<ObjectModel> {
    if layout.patches.len() != model.parts.len()
        || layout
            .patches
            .iter()
            .zip(&model.parts)
            .any(|(p, part)| p.len() != part.mesh.triangles.len())
    {
        return Err(invalid(
            "the layout is not of this model's tessellation".into(),
        ));
    }
    let atlas = Arc::new(
        Arc::unwrap_or_clone(atlas).with_wrap(WrapMode::ClampToEdge, WrapMode::ClampToEdge),
    );
    let surfaces = layout.surfaces(atlas)?;
    let mut out = model.clone();
    for (part, surface) in out.parts.iter_mut().zip(surfaces) {
        part.surface = None;
        *part = part.clone().with_surface(Arc::new(surface))?;
    }
    Ok(out)
}

/// A fingerprint of the model's tessellation (each part's triangles by their corners'
/// positions, bit for bit, in a canonical order, and the layout rule's version): 16 hex
/// digits of FNV-1a. Two models with the same fingerprint lay out the same atlas; a shape
/// edit that moves a vertex or changes a triangle changes it; renumbering the vertices or
/// reordering the triangles does not. Part names, colours and joints do not enter.
pub fn tessellation_fingerprint(model: &ObjectModel) -> String {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    let mut eat = |bytes: &[u8]| {
        for &b in bytes {
            h ^= u64::from(b);
            h = h.wrapping_mul(0x0000_0100_0000_01b3);
        }
    };
    eat(&ATLAS_LAYOUT_VERSION.to_le_bytes());
    eat(&(model.parts.len() as u64).to_le_bytes());
    for part in &model.parts {
        let mut keys: Vec<[u64; 9]> = (0..part.mesh.triangles.len())
            .map(|t| triangle_key(part.mesh.triangle(t)).0)
            .collect();
        keys.sort_unstable();
        eat(&(keys.len() as u64).to_le_bytes());
        for k in &keys {
            for v in k {
                eat(&v.to_le_bytes());
            }
        }
    }
    format!("{h:016x}")
}

/// The barycentric coordinates of the point of triangle `t` nearest `p`, and its distance.
fn closest_on_triangle(p: &Point3, t: &[Point3; 3]) -> ([f64; 3], f64) {
    let (a, b, c) = (t[0], t[1], t[2]);
    let (ab, ac, ap) = (b - a, c - a, p - a);
    let (d1, d2) = (ab.dot(&ap), ac.dot(&ap));
    let bary = 'found: {
        if d1 <= 0.0 && d2 <= 0.0 {
            break 'found [1.0, 0.0, 0.0];
        }
        let bp = p - b;
        let (d3, d4) = (ab.dot(&bp), ac.dot(&bp));
        if d3 >= 0.0 && d4 <= d3 {
            break 'found [0.0, 1.0, 0.0];
        }
        let vc = d1 * d4 - d3 * d2;
        if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
            let v = d1 / (d1 - d3);
            break 'found [1.0 - v, v, 0.0];
        }
        let cp = p - c;
        let (d5, d6) = (ab.dot(&cp), ac.dot(&cp));
        if d6 >= 0.0 && d5 <= d6 {
            break 'found [0.0, 0.0, 1.0];
        }
        let vb = d5 * d2 - d1 * d6;
        if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
            let w = d2 / (d2 - d6);
            break 'found [1.0 - w, 0.0, w];
        }
        let va = d3 * d6 - d5 * d4;
        if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
            let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
            break 'found [0.0, 1.0 - w, w];
        }
        let denom = va + vb + vc;
        if !(denom.is_finite() && denom.abs() > 0.0) {
            break 'found [1.0 / 3.0; 3];
        }
        let (v, w) = (vb / denom, vc / denom);
        [1.0 - v - w, v, w]
    };
    let q = a.coords * bary[0] + b.coords * bary[1] + c.coords * bary[2];
    (bary, (p.coords - q).norm())
}

/// A baked atlas moved from the tessellation it was baked on to another triangulation of
/// the same surface (a script's booleans may split a flat face along other diagonals from
/// one build to the next).
pub struct AtlasTransfer<'a> {
    /// The baked model's triangles (per part, as its layout was made from) and layout.
    pub baked: &'a ObjectModel,
    pub baked_layout: &'a AtlasLayout,
    /// RGBA texels of the baked atlas.
    pub baked_rgba: &'a [u8],
}

impl AtlasTransfer<'_> {
    fn sample(&self, part: usize, tri: usize, bary: [f64; 3]) -> [u8; 4] {
        let patch = &self.baked_layout.patches[part][tri];
        let x = bary[0] * patch.corners[0][0]
            + bary[1] * patch.corners[1][0]
            + bary[2] * patch.corners[2][0];
        let y = bary[0] * patch.corners[0][1]
            + bary[1] * patch.corners[1][1]
            + bary[2] * patch.corners[2][1];
        let w = self.baked_layout.width as i64;
        let h = self.baked_layout.height as i64;
        let (xi, yi) = (
            (x.floor() as i64).clamp(0, w - 1),
            (y.floor() as i64).clamp(0, h - 1),
        );
        let k = 4 * (yi * w + xi) as usize;
        let mut out = [0u8; 4];
        out.copy_from_slice(&self.baked_rgba[k..k + 4]);
        out
    }

    /// The RGBA atlas of `layout` (`model`'s) with each texel the baked colour at its point:
    /// a triangle found among the baked ones by its corners reads its own patch; any other
    /// reads the baked triangle that holds its point within `tolerance` (model units).
    /// `Err(n)`: `n` texels' points lie on no baked triangle (the shape changed).
    pub fn onto(
        &self,
        model: &ObjectModel,
        layout: &AtlasLayout,
        tolerance: f64,
    ) -> std::result::Result<Vec<u8>, usize> {
        if self.baked.parts.len() != model.parts.len()
            || self.baked_rgba.len() != 4 * self.baked_layout.texel_count()
        {
            return Err(1);
        }
        let mut out = vec![0u8; 4 * layout.texel_count()];
        let mut missing = 0usize;
        for (p, part) in model.parts.iter().enumerate() {
            let baked = &self.baked.parts[p].mesh;
            let baked_tris: Vec<[Point3; 3]> = (0..baked.triangles.len())
                .map(|t| baked.triangle(t))
                .collect();
            let mut by_key = std::collections::BTreeMap::new();
            for (t, tri) in baked_tris.iter().enumerate() {
                by_key.entry(triangle_key(*tri).0).or_insert(t);
            }
            let current_keys: std::collections::BTreeSet<[u64; 9]> = (0..part.mesh.triangles.len())
                .map(|t| triangle_key(part.mesh.triangle(t)).0)
                .collect();
            // Baked triangles the current mesh does not have: where its other ones lie.
            let unmatched: Vec<usize> = (0..baked_tris.len())
                .filter(|&t| !current_keys.contains(&triangle_key(baked_tris[t]).0))
                .collect();
            for (t, patch) in layout.patches[p].iter().enumerate() {
                let tri = part.mesh.triangle(t);
                let own = by_key.get(&triangle_key(tri).0).copied();
                for y in patch.y0..patch.y0 + patch.height {
                    for x in patch.x0..patch.x0 + patch.width {
                        let b = patch.texel_barycentric(x, y);
                        let point = Point3::from(
                            tri[0].coords * b[0] + tri[1].coords * b[1] + tri[2].coords * b[2],
                        );
                        let found = match own {
                            Some(bt) => Some((bt, closest_on_triangle(&point, &baked_tris[bt]).0)),
                            None => unmatched
                                .iter()
                                .map(|&bt| (bt, closest_on_triangle(&point, &baked_tris[bt])))
                                .filter(|(_, (_, d))| *d <= tolerance)
                                .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))
                                .map(|(bt, (bary, _))| (bt, bary)),
                        };
                        let k = 4 * (y * layout.width + x) as usize;
                        match found {
                            Some((bt, bary)) => {
                                out[k..k + 4].copy_from_slice(&self.sample(p, bt, bary))
                            }
                            None => missing += 1,
                        }
                    }
                }
            }
        }
        if missing > 0 {
            Err(missing)
        } else {
            Ok(out)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::kinematics::KinematicTree;
    use crate::model::Part;
    use crate::primitives::cuboid;

    fn boxes() -> ObjectModel {
        ObjectModel {
            parts: vec![
                Part::new("a", cuboid(1.0, 0.5, 0.25).expect("box"), [0.2, 0.4, 0.6]),
                Part::new("b", cuboid(0.1, 0.1, 0.1).expect("box"), [0.9, 0.1, 0.1]),
            ],
            tree: KinematicTree::rigid(2),
        }
    }

    #[test]
    fn patches_do_not_overlap_and_hold_their_triangles_at_scale() {
        let model = boxes();
        let d = 40.0;
        let layout = AtlasLayout::new(&model, d, 128).expect("layout");
        let mut used = vec![false; layout.texel_count()];
        for (p, patches) in layout.patches.iter().enumerate() {
            for (t, patch) in patches.iter().enumerate() {
                assert!(patch.x0 + patch.width <= layout.width);
                assert!(patch.y0 + patch.height <= layout.height);
                for y in patch.y0..patch.y0 + patch.height {
                    for x in patch.x0..patch.x0 + patch.width {
                        let k = (y * layout.width + x) as usize;
                        assert!(!used[k], "texel {x},{y} in two rectangles");
                        used[k] = true;
                    }
                }
                // The triangle's edges keep their lengths × the density.
                let tri = model.parts[p].mesh.triangle(t);
                for i in 0..3 {
                    let j = (i + 1) % 3;
                    let flat = ((patch.corners[i][0] - patch.corners[j][0]).powi(2)
                        + (patch.corners[i][1] - patch.corners[j][1]).powi(2))
                    .sqrt();
                    assert!((flat - (tri[i] - tri[j]).norm() * d).abs() < 1e-9);
                }
                // Corners inside the rectangle, off its gutter.
                for c in patch.corners {
                    assert!(c[0] >= f64::from(patch.x0 + GUTTER_TEXELS) - 1e-9);
                    assert!(c[0] <= f64::from(patch.x0 + patch.width - GUTTER_TEXELS) + 1e-9);
                    assert!(c[1] >= f64::from(patch.y0 + GUTTER_TEXELS) - 1e-9);
                    assert!(c[1] <= f64::from(patch.y0 + patch.height - GUTTER_TEXELS) + 1e-9);
                }
            }
        }
        // Laying out again gives the same atlas.
        assert_eq!(AtlasLayout::new(&model, d, 128).expect("again"), layout);
        // A triangle wider than the atlas is refused, naming it.
        let e = AtlasLayout::new(&model, 1000.0, 64).expect_err("too wide");
        assert!(e.to_string().contains("part `a`"), "{e}");
    }

    #[test]
    fn texels_outside_a_triangle_stand_for_its_nearest_point() {
        let t = [[1.0, 1.0], [5.0, 1.0], [1.0, 5.0]];
        let inside = barycentric_2d([2.0, 2.0], t);
        assert!((inside[0] - 0.5).abs() < 1e-12 && (inside[1] - 0.25).abs() < 1e-12);
        // Past the hypotenuse: onto it.
        let b = barycentric_2d([5.0, 5.0], t);
        assert!(b[0].abs() < 1e-12 && (b[1] - 0.5).abs() < 1e-12, "{b:?}");
        // Past a corner: the corner.
        let c = barycentric_2d([0.0, 0.0], t);
        assert!((c[0] - 1.0).abs() < 1e-12, "{c:?}");
    }

    #[test]
    fn the_fingerprint_follows_the_tessellation_only() {
        let a = boxes();
        let mut renamed = a.clone();
        renamed.parts[0].name = "other".into();
        renamed.parts[0].color = [0.0; 3];
        assert_eq!(
            tessellation_fingerprint(&a),
            tessellation_fingerprint(&renamed)
        );
        // The same triangles in another order, their corners rotated and their vertices
        // renumbered: the same fingerprint, and each triangle keeps its texels.
        let mut shuffled = a.clone();
        let mesh = &a.parts[0].mesh;
        let n = mesh.positions.len() as u32;
        let positions: Vec<_> = mesh.positions.iter().rev().copied().collect();
        let triangles: Vec<[u32; 3]> = mesh
            .triangles
            .iter()
            .rev()
            .map(|t| [n - 1 - t[1], n - 1 - t[2], n - 1 - t[0]])
            .collect();
        shuffled.parts[0] = Part::new("a", crate::TriMesh::new(positions, triangles), [0.2; 3]);
        assert_eq!(
            tessellation_fingerprint(&a),
            tessellation_fingerprint(&shuffled)
        );
        let (la, ls) = (
            AtlasLayout::new(&a, 30.0, 128).expect("a"),
            AtlasLayout::new(&shuffled, 30.0, 128).expect("shuffled"),
        );
        let count = mesh.triangles.len();
        for t in 0..count {
            let (pa, ps) = (la.patches[0][t], ls.patches[0][count - 1 - t]);
            assert_eq!((pa.x0, pa.y0), (ps.x0, ps.y0), "triangle {t}");
            // Corner c of the original is corner (c + 2) % 3 of the shuffled one.
            for c in 0..3 {
                let (x, y) = (pa.corners[c], ps.corners[(c + 2) % 3]);
                assert!((x[0] - y[0]).abs() < 1e-9 && (x[1] - y[1]).abs() < 1e-9);
            }
        }
        let mut moved = a.clone();
        moved.parts[1] = Part::new("b", cuboid(0.1, 0.1, 0.12).expect("box"), [0.9, 0.1, 0.1]);
        assert_ne!(
            tessellation_fingerprint(&a),
            tessellation_fingerprint(&moved)
        );
    }

    #[test]
    fn a_bake_moves_onto_another_triangulation_of_the_same_surface_only() {
        // A square split along one diagonal, then along the other.
        let square = |diagonal: bool| {
            let positions = vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(1.0, 1.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
            ];
            let triangles = if diagonal {
                vec![[0, 1, 2], [0, 2, 3]]
            } else {
                vec![[0, 1, 3], [1, 2, 3]]
            };
            ObjectModel {
                parts: vec![Part::new(
                    "sq",
                    crate::TriMesh::new(positions, triangles),
                    [0.5; 3],
                )],
                tree: KinematicTree::rigid(1),
            }
        };
        let (a, b) = (square(true), square(false));
        let (la, lb) = (
            AtlasLayout::new(&a, 16.0, 64).expect("a"),
            AtlasLayout::new(&b, 16.0, 64).expect("b"),
        );
        // Red where x < 0.5, blue elsewhere, painted through a's layout.
        let mut rgba = vec![0u8; 4 * la.texel_count()];
        for (t, patch) in la.patches[0].iter().enumerate() {
            let tri = a.parts[0].mesh.triangle(t);
            for y in patch.y0..patch.y0 + patch.height {
                for x in patch.x0..patch.x0 + patch.width {
                    let w = patch.texel_barycentric(x, y);
                    let px = w[0] * tri[0].x + w[1] * tri[1].x + w[2] * tri[2].x;
                    let k = 4 * (y * la.width + x) as usize;
                    let c = if px < 0.5 {
                        [255, 0, 0, 255]
                    } else {
                        [0, 0, 255, 255]
                    };
                    rgba[k..k + 4].copy_from_slice(&c);
                }
            }
        }
        let transfer = AtlasTransfer {
            baked: &a,
            baked_layout: &la,
            baked_rgba: &rgba,
        };
        let moved = transfer.onto(&b, &lb, 1e-9).expect("same surface");
        let tex = Texture::new(
            "moved",
            lb.width,
            lb.height,
            moved
                .chunks_exact(4)
                .flat_map(|c| [c[0], c[1], c[2]])
                .collect(),
        )
        .expect("texture");
        let coloured = with_atlas(&b, &lb, Arc::new(tex)).expect("apply");
        let s = coloured.parts[0].surface.as_ref().expect("surface");
        // Triangle [0, 1, 3] of b: its corner at (0,0) is red, at (1,0) blue.
        assert_eq!(s.color_at(0, [0.9, 0.05, 0.05]), [1.0, 0.0, 0.0]);
        assert_eq!(s.color_at(0, [0.05, 0.9, 0.05]), [0.0, 0.0, 1.0]);
        // A different surface (the square raised) finds no baked triangle.
        let mut raised = b.clone();
        let mut mesh = (*raised.parts[0].mesh).clone();
        mesh.positions[2].z = 0.1;
        raised.parts[0] = Part::new("sq", mesh, [0.5; 3]);
        let lr = AtlasLayout::new(&raised, 16.0, 64).expect("raised");
        assert!(transfer.onto(&raised, &lr, 1e-9).is_err());
    }

    #[test]
    fn an_atlas_colours_each_triangle_from_its_rectangle() {
        let model = boxes();
        let layout = AtlasLayout::new(&model, 20.0, 64).expect("layout");
        // Every texel of triangle 3 of part 0 red, the rest grey.
        let mut rgb = vec![128u8; 3 * layout.texel_count()];
        let patch = layout.patches[0][3];
        for y in patch.y0..patch.y0 + patch.height {
            for x in patch.x0..patch.x0 + patch.width {
                let k = 3 * (y * layout.width + x) as usize;
                rgb[k..k + 3].copy_from_slice(&[255, 0, 0]);
            }
        }
        let tex = Texture::new("atlas", layout.width, layout.height, rgb).expect("texture");
        let baked = with_atlas(&model, &layout, Arc::new(tex)).expect("baked");
        let s = baked.parts[0].surface.as_ref().expect("surface");
        for bary in [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.2, 0.3, 0.5]] {
            assert_eq!(s.color_at(3, bary), [1.0, 0.0, 0.0]);
            let grey = s.color_at(4, bary);
            assert!((grey[0] - 128.0 / 255.0).abs() < 1e-6, "{grey:?}");
        }
    }
}
