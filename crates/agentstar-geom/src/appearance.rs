//! A mesh's appearance beyond one colour per part: materials (a base colour and an optional
//! texture), texture coordinates and vertex colours per triangle corner, and the colour of
//! any point of a triangle (bilinear texture samples with glTF's wrap modes).
//!
//! Corner attributes are stored per triangle (`[corner 0, corner 1, corner 2]`), not per
//! vertex, so they do not depend on how a file shares its vertices: a seam of a texture
//! needs no split vertices, and welding or re-indexing positions leaves them valid.
//!
//! Colours are the values an image shows (0–1, as `#rrggbb / 255` gives them, the same
//! space as [`crate::Part::color`]); texels are 8-bit values in that space.

use crate::mesh::TriMesh;
use crate::{GeomError, Result};
use std::sync::Arc;

/// What a texture coordinate outside [0, 1] samples (glTF's sampler wrap modes).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum WrapMode {
    /// The texture tiles (glTF's default, OBJ's and PLY's behaviour).
    #[default]
    Repeat,
    /// The texture tiles, every other copy mirrored.
    MirroredRepeat,
    /// The edge texels extend outwards.
    ClampToEdge,
}

impl WrapMode {
    /// The texel index along one axis of `size` texels for an integer index `i`.
    fn texel(self, i: i64, size: u32) -> usize {
        let n = i64::from(size);
        let k = match self {
            WrapMode::Repeat => i.rem_euclid(n),
            WrapMode::MirroredRepeat => {
                let m = i.rem_euclid(2 * n);
                if m >= n {
                    2 * n - 1 - m
                } else {
                    m
                }
            }
            WrapMode::ClampToEdge => i.clamp(0, n - 1),
        };
        k as usize
    }
}

/// An RGB image sampled by texture coordinates: `(u, v) = (0, 0)` is the top-left corner
/// of the image (glTF's convention; OBJ and PLY readers flip `v`), `(1, 1)` the
/// bottom-right.
#[derive(Clone, PartialEq)]
pub struct Texture {
    /// Where it came from (a file name), for messages.
    pub source: String,
    width: u32,
    height: u32,
    /// Row-major RGB, top row first.
    rgb: Vec<u8>,
    pub wrap_u: WrapMode,
    pub wrap_v: WrapMode,
}

impl std::fmt::Debug for Texture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Texture")
            .field("source", &self.source)
            .field("width", &self.width)
            .field("height", &self.height)
            .field("wrap_u", &self.wrap_u)
            .field("wrap_v", &self.wrap_v)
            .finish()
    }
}

impl Texture {
    /// A texture of `width × height` texels from row-major RGB bytes.
    pub fn new(source: impl Into<String>, width: u32, height: u32, rgb: Vec<u8>) -> Result<Self> {
        let source = source.into();
        let expected = (width as usize)
            .checked_mul(height as usize)
            .and_then(|n| n.checked_mul(3));
        if width == 0 || height == 0 || expected != Some(rgb.len()) {
            return Err(GeomError::InvalidArgument {
                primitive: "texture".into(),
                reason: format!(
                    "`{source}`: {width}×{height} texels need {} RGB bytes, got {}",
                    expected.unwrap_or(usize::MAX),
                    rgb.len()
                ),
            });
        }
        Ok(Texture {
            source,
            width,
            height,
            rgb,
            wrap_u: WrapMode::Repeat,
            wrap_v: WrapMode::Repeat,
        })
    }

    pub fn with_wrap(mut self, wrap_u: WrapMode, wrap_v: WrapMode) -> Self {
        self.wrap_u = wrap_u;
        self.wrap_v = wrap_v;
        self
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// Row-major RGB bytes, top row first.
    pub fn rgb(&self) -> &[u8] {
        &self.rgb
    }

    fn texel(&self, x: usize, y: usize) -> [f32; 3] {
        let k = 3 * (y * self.width as usize + x);
        [
            f32::from(self.rgb[k]) / 255.0,
            f32::from(self.rgb[k + 1]) / 255.0,
            f32::from(self.rgb[k + 2]) / 255.0,
        ]
    }

    /// The bilinear sample at `(u, v)`: texel centres sit at `(i + ½) / width`, and the
    /// wrap modes decide the neighbours past the edges.
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 3] {
        let (u, v) = (
            if uv[0].is_finite() { uv[0] } else { 0.0 },
            if uv[1].is_finite() { uv[1] } else { 0.0 },
        );
        // In f64 so that large repeated coordinates keep their fraction.
        let x = f64::from(u) * f64::from(self.width) - 0.5;
        let y = f64::from(v) * f64::from(self.height) - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        let (x0, y0) = (x0.clamp(-1e15, 1e15) as i64, y0.clamp(-1e15, 1e15) as i64);
        let xa = self.wrap_u.texel(x0, self.width);
        let xb = self.wrap_u.texel(x0 + 1, self.width);
        let ya = self.wrap_v.texel(y0, self.height);
        let yb = self.wrap_v.texel(y0 + 1, self.height);
        let (c00, c10, c01, c11) = (
            self.texel(xa, ya),
            self.texel(xb, ya),
            self.texel(xa, yb),
            self.texel(xb, yb),
        );
        std::array::from_fn(|i| {
            let top = c00[i] + (c10[i] - c00[i]) * fx;
            let bottom = c01[i] + (c11[i] - c01[i]) * fx;
            top + (bottom - top) * fy
        })
    }
}

/// A base colour and an optional texture that multiplies it.
#[derive(Debug, Clone, PartialEq)]
pub struct Material {
    pub name: String,
    pub color: [f32; 3],
    pub texture: Option<Arc<Texture>>,
}

/// Per-triangle appearance of one mesh: each triangle's material, and optionally each
/// corner's texture coordinates and colour. A point's colour is its material's colour ×
/// its texture sample (where the material has a texture) × its vertex colour (where the
/// mesh has vertex colours), each interpolated over the triangle.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceAppearance {
    materials: Vec<Material>,
    triangle_material: Vec<u16>,
    corner_uv: Option<Vec<[[f32; 2]; 3]>>,
    corner_color: Option<Vec<[[f32; 3]; 3]>>,
}

fn invalid(reason: String) -> GeomError {
    GeomError::InvalidArgument {
        primitive: "surface appearance".into(),
        reason,
    }
}

impl SurfaceAppearance {
    /// Checks that every triangle names a material and that the corner attributes have one
    /// entry per triangle; a texture without texture coordinates is an error (the caller
    /// drops it with a warning first).
    pub fn new(
        materials: Vec<Material>,
        triangle_material: Vec<u16>,
        corner_uv: Option<Vec<[[f32; 2]; 3]>>,
        corner_color: Option<Vec<[[f32; 3]; 3]>>,
    ) -> Result<Self> {
        let n = triangle_material.len();
        if materials.is_empty() || materials.len() > usize::from(u16::MAX) {
            return Err(invalid(format!(
                "{} materials; a surface has 1 to {}",
                materials.len(),
                u16::MAX
            )));
        }
        if let Some(&m) = triangle_material
            .iter()
            .find(|&&m| usize::from(m) >= materials.len())
        {
            return Err(invalid(format!(
                "a triangle names material {m} of {}",
                materials.len()
            )));
        }
        if corner_uv.as_ref().is_some_and(|c| c.len() != n) {
            return Err(invalid(format!(
                "texture coordinates for {} triangles, the mesh has {n}",
                corner_uv.as_ref().map_or(0, Vec::len)
            )));
        }
        if corner_color.as_ref().is_some_and(|c| c.len() != n) {
            return Err(invalid(format!(
                "vertex colours for {} triangles, the mesh has {n}",
                corner_color.as_ref().map_or(0, Vec::len)
            )));
        }
        if corner_uv.is_none() {
            if let Some(m) = materials.iter().find(|m| m.texture.is_some()) {
                return Err(invalid(format!(
                    "material `{}` has a texture but the mesh has no texture coordinates",
                    m.name
                )));
            }
        }
        Ok(SurfaceAppearance {
            materials,
            triangle_material,
            corner_uv,
            corner_color,
        })
    }

    /// One material of one colour for `triangles` triangles with these corner colours.
    pub fn vertex_colored(corner_color: Vec<[[f32; 3]; 3]>) -> Result<Self> {
        let n = corner_color.len();
        SurfaceAppearance::new(
            vec![Material {
                name: "vertex colours".into(),
                color: [1.0; 3],
                texture: None,
            }],
            vec![0; n],
            None,
            Some(corner_color),
        )
    }

    pub fn triangle_count(&self) -> usize {
        self.triangle_material.len()
    }

    pub fn materials(&self) -> &[Material] {
        &self.materials
    }

    pub fn triangle_material(&self) -> &[u16] {
        &self.triangle_material
    }

    pub fn corner_uv(&self) -> Option<&[[[f32; 2]; 3]]> {
        self.corner_uv.as_deref()
    }

    pub fn corner_color(&self) -> Option<&[[[f32; 3]; 3]]> {
        self.corner_color.as_deref()
    }

    /// True when some triangle's colour varies over it or from its neighbours' beyond its
    /// material's colour: a texture or vertex colours, or more than one material.
    pub fn varies(&self) -> bool {
        self.corner_color.is_some()
            || self.materials.len() > 1
            || self.materials.iter().any(|m| m.texture.is_some())
    }

    /// The colour at barycentric coordinates `bary` (summing to 1) of triangle `triangle`;
    /// grey for a triangle index out of range.
    pub fn color_at(&self, triangle: usize, bary: [f32; 3]) -> [f32; 3] {
        let Some(&m) = self.triangle_material.get(triangle) else {
            return [0.7; 3];
        };
        let material = &self.materials[usize::from(m)];
        let mut c = material.color;
        if let (Some(texture), Some(uv)) = (&material.texture, &self.corner_uv) {
            let t = &uv[triangle];
            let at = [
                bary[0] * t[0][0] + bary[1] * t[1][0] + bary[2] * t[2][0],
                bary[0] * t[0][1] + bary[1] * t[1][1] + bary[2] * t[2][1],
            ];
            let s = texture.sample(at);
            c = [c[0] * s[0], c[1] * s[1], c[2] * s[2]];
        }
        if let Some(colors) = &self.corner_color {
            let t = &colors[triangle];
            for (i, ci) in c.iter_mut().enumerate() {
                *ci *= bary[0] * t[0][i] + bary[1] * t[1][i] + bary[2] * t[2][i];
            }
        }
        c
    }

    /// The area-weighted mean colour over `mesh` (which this appearance belongs to), from
    /// seven samples per triangle: what a part shows from afar, and its colour where a
    /// consumer knows one colour per part only.
    pub fn mean_color(&self, mesh: &TriMesh) -> [f32; 3] {
        const SAMPLES: [[f32; 3]; 7] = [
            [1.0 / 3.0, 1.0 / 3.0, 1.0 / 3.0],
            [2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0],
            [1.0 / 6.0, 2.0 / 3.0, 1.0 / 6.0],
            [1.0 / 6.0, 1.0 / 6.0, 2.0 / 3.0],
            [1.0 / 6.0, 5.0 / 12.0, 5.0 / 12.0],
            [5.0 / 12.0, 1.0 / 6.0, 5.0 / 12.0],
            [5.0 / 12.0, 5.0 / 12.0, 1.0 / 6.0],
        ];
        let mut sum = [0.0f64; 3];
        let mut weight = 0.0f64;
        for t in 0..mesh.triangles.len().min(self.triangle_count()) {
            let [a, b, c] = mesh.triangle(t);
            let area = (b - a).cross(&(c - a)).norm();
            if !(area.is_finite() && area > 0.0) {
                continue;
            }
            for s in SAMPLES {
                let col = self.color_at(t, s);
                for i in 0..3 {
                    sum[i] += area * f64::from(col[i]);
                }
            }
            weight += area * SAMPLES.len() as f64;
        }
        if weight <= 0.0 {
            return self.materials[0].color;
        }
        sum.map(|v| (v / weight) as f32)
    }

    /// The same appearance after the mesh's triangles swapped their second and third
    /// corners ([`TriMesh::transform_affine`] with a mirroring map).
    pub fn with_corners_swapped(&self) -> Self {
        let mut out = self.clone();
        if let Some(uv) = &mut out.corner_uv {
            uv.iter_mut().for_each(|t| t.swap(1, 2));
        }
        if let Some(c) = &mut out.corner_color {
            c.iter_mut().for_each(|t| t.swap(1, 2));
        }
        out
    }

    /// The appearance of `self`'s mesh followed by `other`'s ([`TriMesh::append`]): their
    /// materials side by side; a corner attribute that only one has is filled with the
    /// neutral value (texture coordinates 0, which no material without a texture reads,
    /// and white, which leaves a colour as it is).
    pub fn appended(&self, other: &SurfaceAppearance) -> Result<Self> {
        let offset = self.materials.len();
        if offset + other.materials.len() > usize::from(u16::MAX) {
            return Err(invalid("more than 65535 materials in one part".into()));
        }
        let mut materials = self.materials.clone();
        materials.extend(other.materials.iter().cloned());
        let mut triangle_material = self.triangle_material.clone();
        triangle_material.extend(other.triangle_material.iter().map(|&m| m + offset as u16));
        fn join<T: Copy>(
            a: &Option<Vec<T>>,
            na: usize,
            b: &Option<Vec<T>>,
            nb: usize,
            neutral: T,
        ) -> Option<Vec<T>> {
            if a.is_none() && b.is_none() {
                return None;
            }
            let mut v = a.clone().unwrap_or_else(|| vec![neutral; na]);
            v.extend(b.clone().unwrap_or_else(|| vec![neutral; nb]));
            Some(v)
        }
        let (na, nb) = (self.triangle_count(), other.triangle_count());
        SurfaceAppearance::new(
            materials,
            triangle_material,
            join(&self.corner_uv, na, &other.corner_uv, nb, [[0.0; 2]; 3]),
            join(
                &self.corner_color,
                na,
                &other.corner_color,
                nb,
                [[1.0; 3]; 3],
            ),
        )
    }

    /// The plain appearance of `triangles` triangles of one colour (to append a part that
    /// has no appearance of its own to one that has).
    pub fn plain(name: &str, color: [f32; 3], triangles: usize) -> Self {
        SurfaceAppearance {
            materials: vec![Material {
                name: name.to_string(),
                color,
                texture: None,
            }],
            triangle_material: vec![0; triangles],
            corner_uv: None,
            corner_color: None,
        }
    }
}

/// A mesh read from a file with whatever appearance the file gave it, and what the reader
/// had to say about it (a texture it could not read, a material it did not know).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct AppearedMesh {
    pub mesh: TriMesh,
    pub surface: Option<Arc<SurfaceAppearance>>,
    pub warnings: Vec<String>,
}

impl AppearedMesh {
    pub fn plain(mesh: TriMesh) -> Self {
        AppearedMesh {
            mesh,
            surface: None,
            warnings: Vec::new(),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::primitives::cuboid;

    fn checker() -> Texture {
        // 2×2: red, green / blue, white.
        Texture::new(
            "checker",
            2,
            2,
            vec![255, 0, 0, 0, 255, 0, 0, 0, 255, 255, 255, 255],
        )
        .expect("texture")
    }

    #[test]
    fn bilinear_samples_hit_texel_centres_and_blend_between_them() {
        let t = checker();
        assert_eq!(t.sample([0.25, 0.25]), [1.0, 0.0, 0.0]);
        assert_eq!(t.sample([0.75, 0.75]), [1.0, 1.0, 1.0]);
        // Halfway between red and green.
        let mid = t.sample([0.5, 0.25]);
        assert!((mid[0] - 0.5).abs() < 1e-6 && (mid[1] - 0.5).abs() < 1e-6 && mid[2] == 0.0);
    }

    #[test]
    fn wrap_modes_pick_their_neighbours() {
        let t = checker();
        // One texel left of the left edge's centre row: repeat wraps to green, mirrored and
        // clamped stay on red.
        let u = -0.25;
        assert_eq!(t.sample([u, 0.25]), [0.0, 1.0, 0.0]);
        let m = checker().with_wrap(WrapMode::MirroredRepeat, WrapMode::Repeat);
        assert_eq!(m.sample([u, 0.25]), [1.0, 0.0, 0.0]);
        let c = checker().with_wrap(WrapMode::ClampToEdge, WrapMode::ClampToEdge);
        assert_eq!(c.sample([-3.0, 0.25]), [1.0, 0.0, 0.0]);
        assert_eq!(c.sample([0.25, 7.0]), [0.0, 0.0, 1.0]);
        // Repeat tiles whole copies.
        assert_eq!(t.sample([3.75, -1.25]), [1.0, 1.0, 1.0]);
        // Mirrored: the second copy runs backwards.
        assert_eq!(m.sample([1.25, 0.25]), [0.0, 1.0, 0.0]);
    }

    #[test]
    fn colours_multiply_material_texture_and_vertex_colour() {
        let mesh = cuboid(1.0, 1.0, 1.0).expect("box");
        let n = mesh.triangles.len();
        let s = SurfaceAppearance::new(
            vec![Material {
                name: "m".into(),
                color: [0.5, 1.0, 1.0],
                texture: Some(Arc::new(checker())),
            }],
            vec![0; n],
            Some(vec![[[0.75, 0.75]; 3]; n]),
            Some(vec![[[1.0, 0.5, 1.0]; 3]; n]),
        )
        .expect("surface");
        assert_eq!(s.color_at(0, [1.0, 0.0, 0.0]), [0.5, 0.5, 1.0]);
        let mean = s.mean_color(&mesh);
        assert!(
            (0..3).all(|i| (mean[i] - [0.5, 0.5, 1.0][i]).abs() < 1e-5),
            "{mean:?}"
        );
        assert!(s.varies());
        // Barycentric interpolation of vertex colours.
        let v = SurfaceAppearance::vertex_colored(vec![
            [
                [1.0, 0.0, 0.0],
                [0.0, 1.0, 0.0],
                [0.0, 0.0, 1.0]
            ];
            n
        ])
        .expect("vertex colours");
        let c = v.color_at(3, [0.5, 0.25, 0.25]);
        assert_eq!(c, [0.5, 0.25, 0.25]);
        let swapped = v.with_corners_swapped();
        assert_eq!(swapped.color_at(3, [0.5, 0.25, 0.25]), [0.5, 0.25, 0.25]);
        assert_eq!(swapped.color_at(3, [0.0, 1.0, 0.0]), [0.0, 0.0, 1.0]);
    }

    #[test]
    fn bad_surfaces_are_refused_with_what_is_wrong() {
        let e = SurfaceAppearance::new(
            vec![Material {
                name: "label".into(),
                color: [1.0; 3],
                texture: Some(Arc::new(checker())),
            }],
            vec![0; 2],
            None,
            None,
        )
        .expect_err("texture without coordinates");
        assert!(e.to_string().contains("label"), "{e}");
        let plain = SurfaceAppearance::plain("p", [1.0; 3], 1);
        let e = SurfaceAppearance::new(plain.materials.clone(), vec![1], None, None)
            .expect_err("material out of range");
        assert!(e.to_string().contains("material 1 of 1"), "{e}");
        assert!(Texture::new("x.png", 2, 2, vec![0; 11]).is_err());
    }

    #[test]
    fn appending_keeps_each_sides_colours() {
        let a = SurfaceAppearance::plain("a", [1.0, 0.0, 0.0], 2);
        let b = SurfaceAppearance::vertex_colored(vec![[[0.0, 1.0, 0.0]; 3]; 3]).expect("b");
        let ab = a.appended(&b).expect("appended");
        assert_eq!(ab.triangle_count(), 5);
        assert_eq!(ab.color_at(1, [1.0, 0.0, 0.0]), [1.0, 0.0, 0.0]);
        assert_eq!(ab.color_at(4, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0]);
    }
}
