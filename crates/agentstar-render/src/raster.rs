//! The CPU rasterizer. Coverage follows the pixel-centre convention exactly: pixel (i, j) is
//! covered when the ray through (i + 0.5, j + 0.5) hits a triangle, so silhouettes agree
//! with exact ray casting of the same mesh.
//!
//! Triangles are scan-converted row by row. Each row's span is intersected with the edges
//! computed from canonically ordered endpoints (sorted by (y, x)), so two triangles that
//! share an edge compute bit-identical crossings and no pixel falls through a crack.
//! Triangles crossing the near plane are clipped in camera space before projection.

use agentstar_geom::pose::{Rigid, Similarity};
use agentstar_geom::{Aabb, PinholeCamera, Point3, TriMesh};
use agentstar_mask::BitMask;

/// Points closer than this (planar depth) are clipped away.
pub const NEAR_Z: f64 = 1e-6;

/// `camera_from_mesh` as a 3×3 linear part (scale folded in) and a translation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Affine {
    pub linear: [[f64; 3]; 3],
    pub offset: [f64; 3],
}

impl Affine {
    pub fn from_similarity(s: &Similarity) -> Affine {
        let r = s.rotation.to_rotation_matrix().into_inner() * s.scale;
        Affine {
            linear: [
                [r[(0, 0)], r[(0, 1)], r[(0, 2)]],
                [r[(1, 0)], r[(1, 1)], r[(1, 2)]],
                [r[(2, 0)], r[(2, 1)], r[(2, 2)]],
            ],
            offset: [s.translation.x, s.translation.y, s.translation.z],
        }
    }

    /// `camera_from_object ∘ object_from_part`.
    pub fn camera_from_part(camera_from_object: &Similarity, object_from_part: &Rigid) -> Affine {
        Affine::from_similarity(
            &camera_from_object.compose(&Similarity::from_rigid(object_from_part)),
        )
    }

    #[inline(always)]
    pub fn apply(&self, p: &Point3) -> [f64; 3] {
        let l = &self.linear;
        [
            l[0][0] * p.x + l[0][1] * p.y + l[0][2] * p.z + self.offset[0],
            l[1][0] * p.x + l[1][1] * p.y + l[1][2] * p.z + self.offset[1],
            l[2][0] * p.x + l[2][1] * p.y + l[2][2] * p.z + self.offset[2],
        ]
    }

    /// The camera centre expressed in the mesh frame (for back-face culling decisions).
    pub fn camera_in_mesh(&self) -> Option<Point3> {
        let m = agentstar_geom::Matrix3::from_fn(|r, c| self.linear[r][c]);
        let inv = m.try_inverse()?;
        let o = agentstar_geom::Vector3::from(self.offset);
        Some(Point3::from(-(inv * o)))
    }
}

/// One mesh placed in the camera.
#[derive(Debug, Clone, Copy)]
pub struct Instance<'a> {
    pub mesh: &'a TriMesh,
    /// Bounds of `mesh` in its own frame (precomputed; see `agentstar_geom::Part`).
    pub bounds: Aabb,
    pub camera_from_mesh: Affine,
    /// Edge–face adjacency when the mesh is closed and outward (only front faces can form
    /// its silhouette, and the silhouette can be filled from contour edges alone).
    pub edges: Option<&'a [[u32; 4]]>,
    /// Every edge's triangles when the mesh is not closed
    /// (`agentstar_geom::TriMesh::edge_incidence`): its silhouette is filled from the
    /// outlines of its front faces and of its back faces.
    pub open_edges: Option<&'a [[u32; 4]]>,
    /// With `edges`: each triangle's plane in the mesh frame (`agentstar_geom::Part::planes`),
    /// so a closed mesh's front faces are found without projecting every vertex; `None`
    /// projects them all.
    pub planes: Option<&'a [[f64; 4]]>,
    /// Written into the part-id buffer by the full renderer.
    pub part_id: u16,
}

/// Sorted screen-space vertices of one triangle and its crossing of the row `y`.
#[derive(Clone, Copy)]
pub(crate) struct ScanTriangle {
    v: [[f64; 2]; 3],
    inv01: f64,
    inv12: f64,
    inv02: f64,
}

impl ScanTriangle {
    /// `None` for triangles with zero screen area (they cover no pixel centre generically).
    #[inline(always)]
    pub(crate) fn new(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<ScanTriangle> {
        let mut v = [a, b, c];
        let less = |p: &[f64; 2], q: &[f64; 2]| p[1] < q[1] || (p[1] == q[1] && p[0] < q[0]);
        if less(&v[1], &v[0]) {
            v.swap(0, 1);
        }
        if less(&v[2], &v[1]) {
            v.swap(1, 2);
        }
        if less(&v[1], &v[0]) {
            v.swap(0, 1);
        }
        if v[2][1] == v[0][1] {
            return None;
        }
        let inv = |p: [f64; 2], q: [f64; 2]| {
            if q[1] > p[1] {
                (q[0] - p[0]) / (q[1] - p[1])
            } else {
                0.0
            }
        };
        Some(ScanTriangle {
            inv01: inv(v[0], v[1]),
            inv12: inv(v[1], v[2]),
            inv02: inv(v[0], v[2]),
            v,
        })
    }

    /// Inclusive row range of pixel centres inside the triangle's vertical extent.
    #[inline(always)]
    pub(crate) fn rows(&self, height: u32) -> Option<(u32, u32)> {
        let y0 = ceil_i64(self.v[0][1] - 0.5).max(0);
        let y1 = floor_i64(self.v[2][1] - 0.5).min(height as i64 - 1);
        (y0 <= y1).then_some((y0 as u32, y1 as u32))
    }

    /// Inclusive pixel span of row `j` (pixel centre y = j + 0.5), clamped to the width.
    #[inline(always)]
    pub(crate) fn span(&self, j: u32, width: u32) -> Option<(u32, u32)> {
        let (xl, xr) = self.crossing(j);
        let i0 = ceil_i64(xl - 0.5).max(0);
        let i1 = floor_i64(xr - 0.5).min(width as i64 - 1);
        (i0 <= i1).then_some((i0 as u32, i1 as u32))
    }

    /// Where the line of row `j`'s pixel centres enters and leaves the triangle (x, left
    /// first), for a row in [`ScanTriangle::rows`].
    #[inline(always)]
    fn crossing(&self, j: u32) -> (f64, f64) {
        let y = j as f64 + 0.5;
        let [v0, v1, v2] = self.v;
        let xa = v0[0] + (y - v0[1]) * self.inv02;
        let xb = if y >= v1[1] && v2[1] > v1[1] {
            v1[0] + (y - v1[1]) * self.inv12
        } else {
            v0[0] + (y - v0[1]) * self.inv01
        };
        if xa <= xb {
            (xa, xb)
        } else {
            (xb, xa)
        }
    }
}

/// A triangle's covered stretches, row by row, for [`SilhouetteRenderer::render_spans`].
fn record_triangle(spans: &mut Vec<RowSpan>, st: &ScanTriangle, h: u32) {
    let Some((r0, r1)) = st.rows(h) else { return };
    for row in r0..=r1 {
        let (x0, x1) = st.crossing(row);
        if x1 > x0 {
            spans.push(RowSpan { row, x0, x1 });
        }
    }
}

// `f64::floor` and `f64::ceil` are library calls on baseline x86-64; a truncating cast plus
// a correction is exact for the magnitudes that matter and saturates beyond them (callers
// clamp to the image anyway).
#[inline(always)]
fn floor_i64(a: f64) -> i64 {
    let t = a as i64;
    t - ((a < t as f64) as i64)
}

#[inline(always)]
fn ceil_i64(a: f64) -> i64 {
    let t = a as i64;
    t + ((a > t as f64) as i64)
}

/// A camera-space point in front of the near plane in pixels, as every vertex path
/// projects it (one reciprocal: both vertex paths must give bit-identical positions).
#[inline(always)]
fn to_screen(c: &[f64; 3], camera: &PinholeCamera) -> [f64; 2] {
    let iz = 1.0 / c[2];
    [
        camera.fx * c[0] * iz + camera.cx,
        camera.fy * c[1] * iz + camera.cy,
    ]
}

/// Per-thread scratch for projecting vertices; reused across evaluations so the hot path
/// does not allocate once it has seen the largest mesh.
#[derive(Default, Debug, Clone)]
pub(crate) struct VertexScratch {
    pub cam: Vec<[f64; 3]>,
    pub screen: Vec<[f64; 2]>,
    /// For [`VertexScratch::screen_of`]: the render in which each vertex was last
    /// projected, and the current one's number.
    stamp: Vec<u32>,
    render: u32,
}

impl VertexScratch {
    /// Transforms and projects every vertex; returns true when some vertex is at or behind
    /// the near plane (its triangles need clipping).
    #[inline]
    pub(crate) fn project(&mut self, mesh: &TriMesh, t: &Affine, camera: &PinholeCamera) -> bool {
        let n = mesh.positions.len();
        self.cam.resize(n, [0.0; 3]);
        self.screen.resize(n, [0.0; 2]);
        let mut any_near = false;
        for (i, p) in mesh.positions.iter().enumerate() {
            let c = t.apply(p);
            self.cam[i] = c;
            if c[2] > NEAR_Z {
                self.screen[i] = to_screen(&c, camera);
            } else {
                any_near = true;
            }
        }
        any_near
    }

    /// Starts a render whose vertices [`VertexScratch::screen_of`] projects on demand.
    fn begin_lazy(&mut self, vertices: usize) {
        self.screen.resize(vertices, [0.0; 2]);
        self.stamp.resize(vertices, 0);
        self.render = self.render.wrapping_add(1);
        if self.render == 0 {
            self.stamp.fill(0);
            self.render = 1;
        }
    }

    /// Vertex `v`'s pixel position, projected once per render (every vertex in front of the
    /// near plane: the caller checked the mesh's bounds).
    #[inline(always)]
    fn screen_of(
        &mut self,
        mesh: &TriMesh,
        t: &Affine,
        camera: &PinholeCamera,
        v: u32,
    ) -> [f64; 2] {
        let v = v as usize;
        if self.stamp[v] != self.render {
            self.stamp[v] = self.render;
            self.screen[v] = to_screen(&t.apply(&mesh.positions[v]), camera);
        }
        self.screen[v]
    }
}

/// Clips a camera-space triangle against z > NEAR_Z; returns the polygon (0, 3 or 4 vertices).
pub(crate) fn clip_near(tri: [[f64; 3]; 3]) -> ([[f64; 3]; 4], usize) {
    let mut out = [[0.0; 3]; 4];
    let mut n = 0;
    for k in 0..3 {
        let a = tri[k];
        let b = tri[(k + 1) % 3];
        let (ina, inb) = (a[2] > NEAR_Z, b[2] > NEAR_Z);
        if ina {
            out[n] = a;
            n += 1;
        }
        if ina != inb {
            let t = (NEAR_Z - a[2]) / (b[2] - a[2]);
            // Nudge onto the visible side so the projection is finite.
            let p = [
                a[0] + t * (b[0] - a[0]),
                a[1] + t * (b[1] - a[1]),
                NEAR_Z * (1.0 + 1e-9),
            ];
            if n < 4 {
                out[n] = p;
                n += 1;
            }
        }
    }
    (out, n)
}

pub(crate) fn project_point(c: &[f64; 3], camera: &PinholeCamera) -> [f64; 2] {
    [
        camera.fx * c[0] / c[2] + camera.cx,
        camera.fy * c[1] / c[2] + camera.cy,
    ]
}

impl<'a> Instance<'a> {
    /// `mesh` placed by `camera_from_mesh` as part `part_id`, without edge or plane tables
    /// (filled triangle by triangle): a mesh that is no part of an `ObjectModel`.
    pub fn bare(mesh: &'a TriMesh, camera_from_mesh: Affine, part_id: u16) -> Instance<'a> {
        Instance {
            mesh,
            bounds: mesh.bounds(),
            camera_from_mesh,
            edges: None,
            open_edges: None,
            planes: None,
            part_id,
        }
    }

    pub fn closed(&self) -> bool {
        self.edges.is_some()
    }
}

/// A contour edge: upper and lower endpoints in pixels, its windings of the front faces'
/// and of the back faces' outlines, first and last rows it crosses.
type ContourEdge = ([f64; 2], [f64; 2], i32, i32, u32, u32);

/// Which faces' outlines a contour fill follows.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Sides {
    /// A closed mesh seen from outside: the front faces cover the silhouette.
    Front,
    /// Any mesh: front faces and back faces, each outline on its own.
    Both,
}

/// Scratch for the contour fill: per-face facing, contour edges, per-row crossings.
#[derive(Default, Debug)]
struct ContourScratch {
    /// Per face: 1 front (negative signed area in pixels), -1 back, 0 edge-on.
    facing: Vec<i8>,
    /// Contour edges as (upper endpoint, lower endpoint, winding direction) in pixels, with
    /// the first and last rows whose pixel centres they cross.
    edges: Vec<ContourEdge>,
    /// Per row r, at r + 1: the change in the count of crossings from row r − 1 (edges
    /// starting minus edges that ended), then (summed twice) where row r's crossings
    /// start. All zero between renders: only the rows a render used are summed and
    /// cleared.
    row_start: Vec<u32>,
    /// Where the next crossing of each row goes (read only on the rows in use).
    row_cursor: Vec<u32>,
    crossings: Vec<(f64, i32, i32)>,
}

/// One covered stretch of a row of a render, at sub-pixel precision: the row (its pixel
/// centres at y = row + 0.5) and where the outline crosses that line, `x0 ≤ x1`, in pixels
/// (pixel i spans [i, i + 1)). Stretches of one render may overlap (two parts, two faces).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RowSpan {
    pub row: u32,
    pub x0: f64,
    pub x1: f64,
}

/// Renders silhouettes into a reusable bit mask.
#[derive(Debug)]
pub struct SilhouetteRenderer {
    mask: BitMask,
    scratch: VertexScratch,
    contour: ContourScratch,
    /// Rows written since the last clear (inclusive), so clearing touches only those.
    dirty: Option<(u32, u32)>,
    /// The covered stretches of the last [`SilhouetteRenderer::render_spans`].
    spans: Vec<RowSpan>,
    /// Whether the render in progress records [`RowSpan`]s.
    record: bool,
}

impl SilhouetteRenderer {
    pub fn new(width: u32, height: u32) -> Self {
        SilhouetteRenderer {
            mask: BitMask::new(width, height),
            scratch: VertexScratch::default(),
            contour: ContourScratch::default(),
            dirty: None,
            spans: Vec::new(),
            record: false,
        }
    }

    /// Renders like [`SilhouetteRenderer::render`] and also returns where each covered row
    /// stretch begins and ends at sub-pixel precision (unmerged; rows whose pixel centres
    /// the outline crosses, clipped to the image's rows but not to its width): what a score
    /// smooth in the image's x needs ([`crate::ScoreTarget::soft_gate`]).
    pub fn render_spans(
        &mut self,
        camera: &PinholeCamera,
        instances: &[Instance<'_>],
    ) -> &mut [RowSpan] {
        self.spans.clear();
        self.record = true;
        self.render(camera, instances);
        self.record = false;
        &mut self.spans
    }

    /// The silhouette of `instances` seen by `camera` (whose size must match the renderer's).
    pub fn render(&mut self, camera: &PinholeCamera, instances: &[Instance<'_>]) -> &BitMask {
        if (camera.width, camera.height) != (self.mask.width(), self.mask.height()) {
            self.mask = BitMask::new(camera.width, camera.height);
            self.dirty = None;
        }
        if let Some((a, b)) = self.dirty.take() {
            self.mask.clear_rows(a, b);
        }
        let (w, h) = (camera.width, camera.height);
        let mut dirty = (u32::MAX, 0u32);
        for inst in instances {
            let camera_in_mesh = inst.camera_from_mesh.camera_in_mesh();
            // Culling is only valid when the camera is outside the closed mesh; a camera
            // inside the mesh bounds disables it (cheap and conservative).
            let cull = inst.closed() && !camera_in_bounds(inst, camera_in_mesh);
            // A closed mesh seen from outside, wholly in front of the camera: its front faces
            // from their planes, and only the vertices of its contour projected.
            if let (true, Some(edges), Some(planes), Some(eye)) =
                (cull, inst.edges, inst.planes, camera_in_mesh)
            {
                if camera.fx * camera.fy > 0.0
                    && planes.len() == inst.mesh.triangles.len()
                    && bounds_in_front(inst)
                {
                    self.contour.facing.clear();
                    self.contour.facing.extend(planes.iter().map(|q| {
                        if q[0] * eye.x + q[1] * eye.y + q[2] * eye.z > q[3] {
                            1
                        } else {
                            -1
                        }
                    }));
                    self.scratch.begin_lazy(inst.mesh.positions.len());
                    let scratch = &mut self.scratch;
                    fill_contour(
                        &mut self.mask,
                        &mut self.contour,
                        (edges, Sides::Front),
                        |v| scratch.screen_of(inst.mesh, &inst.camera_from_mesh, camera, v),
                        w,
                        h,
                        &mut dirty,
                        self.record.then_some(&mut self.spans),
                    );
                    continue;
                }
            }
            let any_near = self
                .scratch
                .project(inst.mesh, &inst.camera_from_mesh, camera);
            if !any_near {
                // A closed mesh seen from outside by its front faces' outline; any other
                // (open, or the camera inside its bounds) by both outlines.
                let contour = match (cull, inst.edges, inst.open_edges) {
                    (true, Some(edges), _) => Some((edges, Sides::Front)),
                    (false, Some(edges), _) | (_, None, Some(edges)) => Some((edges, Sides::Both)),
                    _ => None,
                };
                if let Some((edges, sides)) = contour {
                    fill_from_contour(
                        &mut self.mask,
                        &mut self.contour,
                        inst.mesh,
                        (edges, sides),
                        &self.scratch.screen,
                        w,
                        h,
                        &mut dirty,
                        self.record.then_some(&mut self.spans),
                    );
                    continue;
                }
            }
            let screen = &self.scratch.screen;
            let cam = &self.scratch.cam;
            for tri in &inst.mesh.triangles {
                let (ia, ib, ic) = (tri[0] as usize, tri[1] as usize, tri[2] as usize);
                if any_near
                    && (cam[ia][2] <= NEAR_Z || cam[ib][2] <= NEAR_Z || cam[ic][2] <= NEAR_Z)
                {
                    let (poly, n) = clip_near([cam[ia], cam[ib], cam[ic]]);
                    if n >= 3 {
                        let mut p = [[0.0; 2]; 4];
                        for k in 0..n {
                            p[k] = project_point(&poly[k], camera);
                        }
                        for k in 1..n - 1 {
                            if let Some(st) = ScanTriangle::new(p[0], p[k], p[k + 1]) {
                                fill(&mut self.mask, &st, w, h, &mut dirty);
                                if self.record {
                                    record_triangle(&mut self.spans, &st, h);
                                }
                            }
                        }
                    }
                    continue;
                }
                let (a, b, c) = (screen[ia], screen[ib], screen[ic]);
                if cull {
                    // With all depths positive, a front face has negative signed area in
                    // pixel coordinates (see the module docs of `full`).
                    let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
                    if area >= 0.0 {
                        continue;
                    }
                }
                if !may_cover_a_centre(a, b, c, w, h) {
                    continue;
                }
                if let Some(st) = ScanTriangle::new(a, b, c) {
                    fill(&mut self.mask, &st, w, h, &mut dirty);
                    if self.record {
                        record_triangle(&mut self.spans, &st, h);
                    }
                }
            }
        }
        if dirty.0 <= dirty.1 {
            self.dirty = Some(dirty);
        }
        &self.mask
    }

    pub fn mask(&self) -> &BitMask {
        &self.mask
    }

    /// The rows (inclusive) that may hold pixels of the last render; `None` when it is empty.
    /// Every set pixel lies in them, so scores may read only these rows
    /// ([`crate::ScoreTarget::gate_rows`]).
    pub fn rows(&self) -> Option<(u32, u32)> {
        self.dirty
    }
}

pub(crate) fn camera_inside_bounds(inst: &Instance<'_>) -> bool {
    camera_in_bounds(inst, inst.camera_from_mesh.camera_in_mesh())
}

/// [`camera_inside_bounds`] given the camera's centre in the mesh frame.
fn camera_in_bounds(inst: &Instance<'_>, camera_in_mesh: Option<Point3>) -> bool {
    match camera_in_mesh {
        Some(c) => {
            let b = &inst.bounds;
            let pad = b.extent().max() * 1e-6;
            (0..3).all(|i| c[i] >= b.min[i] - pad && c[i] <= b.max[i] + pad)
        }
        None => true,
    }
}

/// True when every corner of the mesh's bounds lies in front of the near plane, and so
/// every vertex (depth is affine in the mesh frame).
fn bounds_in_front(inst: &Instance<'_>) -> bool {
    let (lo, hi) = (inst.bounds.min, inst.bounds.max);
    (0..8).all(|k| {
        let p = Point3::new(
            if k & 1 == 0 { lo.x } else { hi.x },
            if k & 2 == 0 { lo.y } else { hi.y },
            if k & 4 == 0 { lo.z } else { hi.z },
        );
        inst.camera_from_mesh.apply(&p)[2] > NEAR_Z
    })
}

#[inline(always)]
fn fill(mask: &mut BitMask, st: &ScanTriangle, w: u32, h: u32, dirty: &mut (u32, u32)) {
    let Some((r0, r1)) = st.rows(h) else { return };
    let mut any = false;
    for j in r0..=r1 {
        if let Some((x0, x1)) = st.span(j, w) {
            mask.set_span(j, x0, x1);
            any = true;
        }
    }
    if any {
        dirty.0 = dirty.0.min(r0);
        dirty.1 = dirty.1.max(r1);
    }
}

/// True when the screen bounding box of the triangle holds at least one pixel centre of
/// the image; most sub-pixel triangles of dense meshes are rejected here before sorting.
#[inline(always)]
fn may_cover_a_centre(a: [f64; 2], b: [f64; 2], c: [f64; 2], w: u32, h: u32) -> bool {
    let ymin = a[1].min(b[1]).min(c[1]);
    let ymax = a[1].max(b[1]).max(c[1]);
    if ceil_i64(ymin - 0.5).max(0) > floor_i64(ymax - 0.5).min(h as i64 - 1) {
        return false;
    }
    let xmin = a[0].min(b[0]).min(c[0]);
    let xmax = a[0].max(b[0]).max(c[0]);
    ceil_i64(xmin - 0.5).max(0) <= floor_i64(xmax - 0.5).min(w as i64 - 1)
}

/// Fills the silhouette of a mesh (all in front of the near plane) from the outlines of its
/// faces. The edges between front and back faces of a closed mesh seen from outside,
/// oriented as the front faces traverse them, have a winding number equal to minus the
/// number of front layers over each point, so the nonzero rule gives exactly the union of
/// the front faces ([`Sides::Front`]). Any other mesh sums each edge's front faces and its
/// back faces apart (an open mesh's borders, and the camera inside a closed one, show back
/// faces): a pixel is covered where either winding is nonzero ([`Sides::Both`]).
/// The cost grows with the outline, not with the number of triangles or their size.
#[allow(clippy::too_many_arguments)]
fn fill_from_contour(
    mask: &mut BitMask,
    cs: &mut ContourScratch,
    mesh: &TriMesh,
    (edges, sides): (&[[u32; 4]], Sides),
    screen: &[[f64; 2]],
    w: u32,
    h: u32,
    dirty: &mut (u32, u32),
    spans: Option<&mut Vec<RowSpan>>,
) {
    cs.facing.clear();
    cs.facing.extend(mesh.triangles.iter().map(|t| {
        let (a, b, c) = (
            screen[t[0] as usize],
            screen[t[1] as usize],
            screen[t[2] as usize],
        );
        let area = (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0]);
        if area < 0.0 {
            1
        } else if area > 0.0 || sides == Sides::Front {
            // With front faces only, an edge-on face is a back face (as it always was).
            -1
        } else {
            0
        }
    }));
    fill_contour(
        mask,
        cs,
        (edges, sides),
        |v| screen[v as usize],
        w,
        h,
        dirty,
        spans,
    );
}

/// The fill of [`fill_from_contour`] once `cs.facing` holds every face's facing; `screen`
/// gives a vertex's pixel position (called only for the contour's vertices). Each covered
/// stretch is also pushed to `spans` when given.
#[allow(clippy::too_many_arguments)]
fn fill_contour(
    mask: &mut BitMask,
    cs: &mut ContourScratch,
    (edges, sides): (&[[u32; 4]], Sides),
    mut screen: impl FnMut(u32) -> [f64; 2],
    w: u32,
    h: u32,
    dirty: &mut (u32, u32),
    mut spans: Option<&mut Vec<RowSpan>>,
) {
    if cs.row_start.len() != h as usize + 2 {
        cs.row_start.clear();
        cs.row_start.resize(h as usize + 2, 0);
        cs.row_cursor.resize(h as usize + 2, 0);
    }
    // A face index past the faces ([`agentstar_geom::mesh::NO_FACE`]) has facing 0.
    let facing = &cs.facing;
    let of = |f: u32| -> i8 { facing.get(f as usize).copied().unwrap_or(0) };
    cs.edges.clear();
    let (mut row_min, mut row_max) = (i64::MAX, i64::MIN);
    for e in edges {
        let (f, g) = (of(e[2]), of(e[3]));
        // Windings of a → b: the faces traversing it count +1, those traversing b → a −1.
        let front = i32::from(f == 1) - i32::from(g == 1);
        let back = match sides {
            Sides::Front => 0,
            Sides::Both => i32::from(f == -1) - i32::from(g == -1),
        };
        if front == 0 && back == 0 {
            continue;
        }
        let (p, q) = (screen(e[0]), screen(e[1]));
        let (top, bottom, dir) = if p[1] < q[1] {
            (p, q, 1)
        } else if q[1] < p[1] {
            (q, p, -1)
        } else {
            continue;
        };
        // Rows whose centre y satisfies top.y <= y < bottom.y.
        let r0 = ceil_i64(top[1] - 0.5).max(0);
        let r1 = (ceil_i64(bottom[1] - 0.5) - 1).min(h as i64 - 1);
        if r0 > r1 {
            continue;
        }
        row_min = row_min.min(r0);
        row_max = row_max.max(r1);
        // Counted as differences: +1 at the first row, −1 after the last.
        // (u32 wrapping: an entry may hold a net −1, read back as i32 below).
        let (a, b) = (r0 as usize + 1, r1 as usize + 2);
        cs.row_start[a] = cs.row_start[a].wrapping_add(1);
        cs.row_start[b] = cs.row_start[b].wrapping_sub(1);
        cs.edges
            .push((top, bottom, dir * front, dir * back, r0 as u32, r1 as u32));
    }
    if row_min > row_max {
        return;
    }
    let (used0, used1) = (row_min as usize, row_max as usize + 1);
    // row_start[used0] is 0: no row before `row_min` counted a crossing. One pass turns the
    // differences into counts and the counts into where each row's crossings start.
    let (mut count, mut start) = (0i64, 0i64);
    for idx in used0 + 1..=used1 {
        count += i64::from(cs.row_start[idx] as i32);
        start += count;
        cs.row_start[idx] = start as u32;
    }
    // The −1 after the last row (every edge's difference is summed above).
    cs.row_start[used1 + 1] = 0;
    let total = cs.row_start[used1] as usize;
    // Every slot below `total` is written below, exactly once.
    if cs.crossings.len() < total {
        cs.crossings.resize(total, (0.0, 0, 0));
    }
    cs.row_cursor[used0..=used1].copy_from_slice(&cs.row_start[used0..=used1]);
    for &(top, bottom, front, back, r0, r1) in &cs.edges {
        let inv = (bottom[0] - top[0]) / (bottom[1] - top[1]);
        for r in r0..=r1 {
            let y = r as f64 + 0.5;
            let x = top[0] + (y - top[1]) * inv;
            let slot = &mut cs.row_cursor[r as usize];
            cs.crossings[*slot as usize] = (x, front, back);
            *slot += 1;
        }
    }
    for r in row_min..=row_max {
        let (s, e) = (
            cs.row_start[r as usize] as usize,
            cs.row_start[r as usize + 1] as usize,
        );
        let row = &mut cs.crossings[s..e];
        if row.len() <= 16 {
            // Few crossings per row: insertion sort beats a general sort here.
            for i in 1..row.len() {
                let mut k = i;
                while k > 0 && row[k - 1].0 > row[k].0 {
                    row.swap(k - 1, k);
                    k -= 1;
                }
            }
        } else {
            // Many (an open mesh's borders, holes, folds): no quadratic sort.
            row.sort_unstable_by(|a, b| a.0.total_cmp(&b.0));
        }
        let (mut front, mut back) = (0, 0);
        for k in 0..row.len().saturating_sub(1) {
            front += row[k].1;
            back += row[k].2;
            if front != 0 || back != 0 {
                if let Some(spans) = spans.as_deref_mut() {
                    if row[k + 1].0 > row[k].0 {
                        spans.push(RowSpan {
                            row: r as u32,
                            x0: row[k].0,
                            x1: row[k + 1].0,
                        });
                    }
                }
                let i0 = ceil_i64(row[k].0 - 0.5).max(0);
                let i1 = floor_i64(row[k + 1].0 - 0.5).min(w as i64 - 1);
                if i0 <= i1 {
                    mask.set_span(r as u32, i0 as u32, i1 as u32);
                }
            }
        }
    }
    cs.row_start[used0..=used1].fill(0);
    dirty.0 = dirty.0.min(row_min as u32);
    dirty.1 = dirty.1.max(row_max as u32);
}
