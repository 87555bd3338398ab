//! The full renderer: planar depth, part id and camera-frame normal per pixel, with a
//! z-buffer. Coverage is the same scan conversion as the silhouette renderer, so the
//! covered pixels are identical; depth is exact per pixel (ray–plane intersection).
//!
//! Sign convention used for culling: with every depth positive, `n · a = z_a z_b z_c ·
//! area2D(a', b', c')` where `n = (b − a) × (c − a)` and primes are pixel coordinates, so a
//! face looking at the camera (`n · a < 0`) has negative signed area in pixel coordinates.

use crate::raster::{
    camera_inside_bounds, clip_near, project_point, Instance, ScanTriangle, VertexScratch, NEAR_Z,
};
use agentstar_geom::PinholeCamera;

/// Sentinel part id for pixels that show no geometry.
pub const NO_PART: u16 = u16::MAX;

/// Per-pixel render results, row-major.
#[derive(Debug, Clone)]
pub struct RenderBuffers {
    pub width: u32,
    pub height: u32,
    /// Planar camera Z; `f32::INFINITY` where no geometry is seen.
    pub depth: Vec<f32>,
    pub part: Vec<u16>,
    /// Unit camera-frame normal of the visible face, turned toward the camera.
    pub normal: Vec<[f32; 3]>,
    /// The visible triangle's index in its part's mesh (meaningful where `part` is set):
    /// with the depth it gives the surface point, so colour views sample textures there.
    pub triangle: Vec<u32>,
}

impl RenderBuffers {
    pub fn new(width: u32, height: u32) -> Self {
        let n = width as usize * height as usize;
        RenderBuffers {
            width,
            height,
            depth: vec![f32::INFINITY; n],
            part: vec![NO_PART; n],
            normal: vec![[0.0; 3]; n],
            triangle: vec![0; n],
        }
    }
    /// Each of the first `parts` parts' pixels in view (the nearest surface), indexed by
    /// part id.
    pub fn part_pixels(&self, parts: usize) -> Vec<u64> {
        self.part_counts(parts, None, None)
            .into_iter()
            .map(|c| c.0)
            .collect()
    }

    /// Each of the first `parts` parts' pixels in view that `cover` (a mask of the camera's
    /// size, e.g. the hands) leaves uncovered, indexed by part id.
    pub fn part_pixels_outside(&self, parts: usize, cover: &crate::BitMask) -> Vec<u64> {
        self.part_counts(parts, Some(cover), None)
            .into_iter()
            .map(|c| c.0)
            .collect()
    }

    /// Each of the first `parts` parts' pixels in view that `hidden` (the hands, when given)
    /// leaves uncovered, and how many of those lie outside `mask` (the object's mask), indexed
    /// by part id: where each part sits against the frame.
    pub fn part_pixels_off_mask(
        &self,
        parts: usize,
        mask: &crate::BitMask,
        hidden: Option<&crate::BitMask>,
    ) -> Vec<(u64, u64)> {
        self.part_counts(parts, hidden, Some(mask))
    }

    /// The counts behind the three above: per part, its pixels in view outside `hidden`, and
    /// of those the ones outside `mask` (0 without one). Masks of another size than the render
    /// count as covering nothing.
    fn part_counts(
        &self,
        parts: usize,
        hidden: Option<&crate::BitMask>,
        mask: Option<&crate::BitMask>,
    ) -> Vec<(u64, u64)> {
        let mut counts = vec![(0u64, 0u64); parts];
        let inside =
            |m: &crate::BitMask, x: u32, y: u32| x < m.width() && y < m.height() && m.get(x, y);
        for (k, &p) in self.part.iter().enumerate() {
            let Some(c) = counts.get_mut(p as usize) else {
                continue;
            };
            if hidden.is_none() && mask.is_none() {
                c.0 += 1;
                continue;
            }
            let (x, y) = (
                (k % self.width as usize) as u32,
                (k / self.width as usize) as u32,
            );
            if hidden.is_some_and(|h| inside(h, x, y)) {
                continue;
            }
            c.0 += 1;
            if mask.is_some_and(|m| !inside(m, x, y)) {
                c.1 += 1;
            }
        }
        counts
    }

    pub fn covered(&self, x: u32, y: u32) -> bool {
        self.part[(y * self.width + x) as usize] != NO_PART
    }
    pub fn silhouette(&self) -> crate::BitMask {
        crate::BitMask::from_fn(self.width, self.height, |x, y| self.covered(x, y))
    }
}

/// Renders depth, part ids and normals of `instances` seen by `camera`. Back faces are drawn
/// too (open meshes show their inside), but the nearest surface wins.
pub fn render_full(camera: &PinholeCamera, instances: &[Instance<'_>]) -> RenderBuffers {
    let mut r = FullRenderer::default();
    r.render(camera, instances);
    r.buffers
}

/// [`render_full`] into buffers kept between renders: for loops that render many poses
/// (at 640×480 the buffers hold 5.5 MB, which a fresh allocation zeroes every time); each
/// render clears only the rows the previous one drew.
#[derive(Debug, Clone)]
pub struct FullRenderer {
    buffers: RenderBuffers,
    /// Rows (inclusive) the last render may have drawn.
    dirty: Option<(u32, u32)>,
    scratch: VertexScratch,
}

impl Default for FullRenderer {
    fn default() -> Self {
        FullRenderer {
            buffers: RenderBuffers::new(0, 0),
            dirty: None,
            scratch: VertexScratch::default(),
        }
    }
}

impl FullRenderer {
    /// The buffers of `instances` seen by `camera`, as [`render_full`] gives them.
    pub fn render(&mut self, camera: &PinholeCamera, instances: &[Instance<'_>]) -> &RenderBuffers {
        let (w, h) = (camera.width, camera.height);
        if (self.buffers.width, self.buffers.height) != (w, h) {
            self.buffers = RenderBuffers::new(w, h);
        } else if let Some((r0, r1)) = self.dirty {
            let range = (r0 * w) as usize..((r1 + 1) * w) as usize;
            self.buffers.depth[range.clone()].fill(f32::INFINITY);
            self.buffers.part[range.clone()].fill(NO_PART);
            self.buffers.normal[range].fill([0.0; 3]);
        }
        self.dirty = draw_full(camera, instances, &mut self.buffers, &mut self.scratch);
        &self.buffers
    }
}

/// Draws `instances` into cleared buffers of the camera's size; the rows drawn (inclusive).
fn draw_full(
    camera: &PinholeCamera,
    instances: &[Instance<'_>],
    out: &mut RenderBuffers,
    scratch: &mut VertexScratch,
) -> Option<(u32, u32)> {
    let (w, h) = (camera.width, camera.height);
    let mut rows = (u32::MAX, 0u32);
    for inst in instances {
        let any_near = scratch.project(inst.mesh, &inst.camera_from_mesh, camera);
        let cull = inst.closed() && !camera_inside_bounds(inst);
        for (tri_index, tri) in inst.mesh.triangles.iter().enumerate() {
            let tri_index = tri_index as u32;
            let idx = [tri[0] as usize, tri[1] as usize, tri[2] as usize];
            let c = [
                scratch.cam[idx[0]],
                scratch.cam[idx[1]],
                scratch.cam[idx[2]],
            ];
            let e1 = [c[1][0] - c[0][0], c[1][1] - c[0][1], c[1][2] - c[0][2]];
            let e2 = [c[2][0] - c[0][0], c[2][1] - c[0][1], c[2][2] - c[0][2]];
            let n = [
                e1[1] * e2[2] - e1[2] * e2[1],
                e1[2] * e2[0] - e1[0] * e2[2],
                e1[0] * e2[1] - e1[1] * e2[0],
            ];
            let d = n[0] * c[0][0] + n[1] * c[0][1] + n[2] * c[0][2];
            if cull && d >= 0.0 {
                continue;
            }
            let len = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if len == 0.0 {
                continue;
            }
            // Face the camera: flip normals of back faces seen from inside.
            let sign = if d > 0.0 { -1.0 } else { 1.0 };
            let unit = [
                (sign * n[0] / len) as f32,
                (sign * n[1] / len) as f32,
                (sign * n[2] / len) as f32,
            ];
            let mut draw = |st: &ScanTriangle| {
                let Some((r0, r1)) = st.rows(h) else { return };
                rows = (rows.0.min(r0), rows.1.max(r1));
                for j in r0..=r1 {
                    let Some((x0, x1)) = st.span(j, w) else {
                        continue;
                    };
                    let ry = (j as f64 + 0.5 - camera.cy) / camera.fy;
                    for i in x0..=x1 {
                        let rx = (i as f64 + 0.5 - camera.cx) / camera.fx;
                        let denom = n[0] * rx + n[1] * ry + n[2];
                        if denom == 0.0 {
                            continue;
                        }
                        let z = d / denom;
                        if z.is_nan() || z <= NEAR_Z {
                            continue;
                        }
                        let k = (j * w + i) as usize;
                        let zf = z as f32;
                        if zf < out.depth[k] {
                            out.depth[k] = zf;
                            out.part[k] = inst.part_id;
                            out.normal[k] = unit;
                            out.triangle[k] = tri_index;
                        }
                    }
                }
            };
            if any_near && c.iter().any(|p| p[2] <= NEAR_Z) {
                let (poly, m) = clip_near(c);
                if m >= 3 {
                    let p: Vec<[f64; 2]> =
                        poly[..m].iter().map(|q| project_point(q, camera)).collect();
                    for k in 1..m - 1 {
                        if let Some(st) = ScanTriangle::new(p[0], p[k], p[k + 1]) {
                            draw(&st);
                        }
                    }
                }
                continue;
            }
            if let Some(st) = ScanTriangle::new(
                scratch.screen[idx[0]],
                scratch.screen[idx[1]],
                scratch.screen[idx[2]],
            ) {
                draw(&st);
            }
        }
    }
    (rows.0 <= rows.1).then_some(rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::BitMask;

    #[test]
    fn part_pixels_outside_a_cover_leave_the_covered_ones_out() {
        // Row 0: part 0, part 0, part 1; row 1: part 1, nothing, part 0.
        let mut buffers = RenderBuffers::new(3, 2);
        buffers.part = vec![0, 0, 1, 1, NO_PART, 0];
        let cover = BitMask::from_fn(3, 2, |x, _| x == 0);
        assert_eq!(buffers.part_pixels(2), [3, 2]);
        assert_eq!(buffers.part_pixels_outside(2, &cover), [2, 1]);
        // Against an object mask over the first two columns, the cover as the hands: of the
        // pixels left in view (part 0 at (1, 0) and (2, 1), part 1 at (2, 0)), those in the
        // third column lie off the mask.
        let mask = BitMask::from_fn(3, 2, |x, _| x <= 1);
        assert_eq!(
            buffers.part_pixels_off_mask(2, &mask, Some(&cover)),
            [(2, 1), (1, 1)]
        );
        assert_eq!(
            buffers.part_pixels_off_mask(2, &mask, None),
            [(3, 1), (2, 1)]
        );
        // A cover smaller than the render covers nothing beyond its edge.
        assert_eq!(
            buffers.part_pixels_outside(2, &BitMask::from_fn(1, 1, |_, _| true)),
            [2, 2]
        );
    }
}
