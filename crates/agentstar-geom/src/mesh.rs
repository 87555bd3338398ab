//! Indexed triangle meshes: measurement (volume, area, bounds, watertightness), rigid and
//! affine transforms, merging and vertex welding.

use crate::{Matrix3, Point3, Vector3};
use std::collections::HashMap;

/// An axis-aligned bounding box. `min > max` componentwise means empty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Aabb {
    pub min: Point3,
    pub max: Point3,
}

impl Aabb {
    pub fn empty() -> Self {
        Aabb {
            min: Point3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
            max: Point3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x || self.min.y > self.max.y || self.min.z > self.max.z
    }
    pub fn grow(&mut self, p: &Point3) {
        self.min = self.min.inf(p);
        self.max = self.max.sup(p);
    }
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: self.min.inf(&other.min),
            max: self.max.sup(&other.max),
        }
    }
    pub fn center(&self) -> Point3 {
        nalgebra::center(&self.min, &self.max)
    }
    pub fn extent(&self) -> Vector3 {
        if self.is_empty() {
            Vector3::zeros()
        } else {
            self.max - self.min
        }
    }
    pub fn contains(&self, p: &Point3) -> bool {
        (0..3).all(|i| p[i] >= self.min[i] && p[i] <= self.max[i])
    }
    pub fn from_points<'a>(points: impl IntoIterator<Item = &'a Point3>) -> Aabb {
        let mut b = Aabb::empty();
        for p in points {
            b.grow(p);
        }
        b
    }
}

/// The face index of [`TriMesh::edge_incidence`] where an edge has no triangle of a kind.
pub const NO_FACE: u32 = u32::MAX;

/// An indexed triangle mesh in some named frame (the owner says which). Triangles are
/// counter-clockwise seen from outside, so normals point out of closed solids.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<Point3>,
    pub triangles: Vec<[u32; 3]>,
}

impl TriMesh {
    pub fn new(positions: Vec<Point3>, triangles: Vec<[u32; 3]>) -> Self {
        TriMesh {
            positions,
            triangles,
        }
    }

    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    pub fn triangle(&self, i: usize) -> [Point3; 3] {
        let [a, b, c] = self.triangles[i];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    pub fn bounds(&self) -> Aabb {
        Aabb::from_points(self.positions.iter())
    }

    /// Signed volume by the divergence theorem; meaningful for closed, outward meshes.
    pub fn volume(&self) -> f64 {
        let mut v = 0.0;
        for i in 0..self.triangles.len() {
            let [a, b, c] = self.triangle(i);
            v += a.coords.dot(&b.coords.cross(&c.coords));
        }
        v / 6.0
    }

    pub fn area(&self) -> f64 {
        (0..self.triangles.len())
            .map(|i| {
                let [a, b, c] = self.triangle(i);
                (b - a).cross(&(c - a)).norm() * 0.5
            })
            .sum()
    }

    /// True when every undirected edge is shared by exactly two triangles that traverse it
    /// in opposite directions (a closed, consistently oriented 2-manifold edge structure).
    pub fn is_watertight(&self) -> bool {
        if self.triangles.is_empty() {
            return false;
        }
        let mut directed: HashMap<(u32, u32), u32> =
            HashMap::with_capacity(self.triangles.len() * 3);
        for t in &self.triangles {
            for k in 0..3 {
                let e = (t[k], t[(k + 1) % 3]);
                if e.0 == e.1 {
                    return false;
                }
                *directed.entry(e).or_insert(0) += 1;
            }
        }
        directed
            .iter()
            .all(|(&(a, b), &n)| n == 1 && directed.get(&(b, a)) == Some(&1))
    }

    /// Each triangle's plane as `[n.x, n.y, n.z, n·a]` with `n = (b − a) × (c − a)` (not
    /// normalised; outward on an outward-oriented mesh): the triangle faces a point `p`
    /// when `n·p > n·a`.
    pub fn face_planes(&self) -> Vec<[f64; 4]> {
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.positions[i as usize]);
                let n = (b - a).cross(&(c - a));
                [n.x, n.y, n.z, n.dot(&a.coords)]
            })
            .collect()
    }

    /// For a closed, consistently oriented mesh, every undirected edge once as
    /// `[a, b, f0, f1]`: triangle `f0` traverses `a → b` and triangle `f1` traverses `b → a`.
    /// `None` when the mesh is not watertight. Sorted by `(a, b)`.
    pub fn manifold_edges(&self) -> Option<Vec<[u32; 4]>> {
        if !self.is_watertight() {
            return None;
        }
        let mut directed: HashMap<(u32, u32), u32> =
            HashMap::with_capacity(self.triangles.len() * 3);
        for (f, t) in self.triangles.iter().enumerate() {
            for k in 0..3 {
                directed.insert((t[k], t[(k + 1) % 3]), f as u32);
            }
        }
        let mut edges: Vec<[u32; 4]> = directed
            .iter()
            .filter(|(&(a, b), _)| a < b)
            .map(|(&(a, b), &f0)| [a, b, f0, directed[&(b, a)]])
            .collect();
        edges.sort_unstable();
        Some(edges)
    }

    /// Every (triangle, edge) incidence of any mesh (open, with borders, non-manifold) once,
    /// as `[a, b, f, g]` with `a < b`: `f` a triangle that traverses `a → b`, `g` one that
    /// traverses `b → a`, either [`NO_FACE`] when the edge has fewer of that kind. An edge
    /// with more triangles takes several entries. Degenerate triangles' edges are left out.
    /// Sorted, so the order does not depend on hashing.
    pub fn edge_incidence(&self) -> Vec<[u32; 4]> {
        let mut directed: Vec<(u32, u32, u32)> = Vec::with_capacity(self.triangles.len() * 3);
        for (f, t) in self.triangles.iter().enumerate() {
            if t[0] == t[1] || t[1] == t[2] || t[0] == t[2] {
                continue;
            }
            for k in 0..3 {
                directed.push((t[k], t[(k + 1) % 3], f as u32));
            }
        }
        // Grouped by undirected edge: forward (a < b) traversals first, then backward.
        let mut keyed: Vec<(u32, u32, bool, u32)> = directed
            .into_iter()
            .map(|(a, b, f)| (a.min(b), a.max(b), a > b, f))
            .collect();
        keyed.sort_unstable();
        let mut out = Vec::with_capacity(keyed.len() / 2 + 1);
        for group in keyed.chunk_by(|x, y| (x.0, x.1) == (y.0, y.1)) {
            let faces = |backward: bool| group.iter().filter(move |e| e.2 == backward).map(|e| e.3);
            let (forward, backward): (Vec<u32>, Vec<u32>) =
                (faces(false).collect(), faces(true).collect());
            for k in 0..forward.len().max(backward.len()) {
                out.push([
                    group[0].0,
                    group[0].1,
                    forward.get(k).copied().unwrap_or(NO_FACE),
                    backward.get(k).copied().unwrap_or(NO_FACE),
                ]);
            }
        }
        out
    }

    /// The mesh with every hole whose rim is a simple loop no longer than `max_rim` closed by
    /// a fan about the rim's centroid, wound against the faces along the rim so the closed
    /// mesh keeps their orientation; with how many holes it closed. Holes that touch at a
    /// vertex (a pinch: several rims through it) are one hole here: the vertex is split once
    /// per fan of faces around it ([`TriMesh::with_pinches_split`]) and their rims join into
    /// one loop through its copies. Larger holes and open sheets' outer rims longer than the
    /// bound stay as they are; with nothing closed the mesh comes back unchanged.
    pub fn with_small_holes_closed(&self, max_rim: f64) -> (TriMesh, usize) {
        if max_rim.is_nan() || max_rim <= 0.0 {
            return (self.clone(), 0);
        }
        let split = self.with_pinches_split();
        let borders = split.border_edges();
        if borders.is_empty() {
            return (self.clone(), 0);
        }
        let mut outgoing: HashMap<u32, Vec<usize>> = HashMap::new();
        let mut incoming: HashMap<u32, usize> = HashMap::new();
        for (k, &(a, b)) in borders.iter().enumerate() {
            outgoing.entry(a).or_default().push(k);
            *incoming.entry(b).or_default() += 1;
        }
        let simple = |v: u32| {
            outgoing.get(&v).map_or(0, Vec::len) == 1 && incoming.get(&v).copied() == Some(1)
        };
        let mut out = split.clone();
        let mut visited = vec![false; borders.len()];
        let mut closed = 0;
        for start in 0..borders.len() {
            if visited[start] {
                continue;
            }
            let mut rim = Vec::new();
            let mut k = start;
            let is_loop = loop {
                visited[k] = true;
                rim.push(k);
                let to = borders[k].1;
                if !simple(to) || rim.len() > borders.len() {
                    break false;
                }
                k = outgoing[&to][0];
                if k == start {
                    break true;
                }
                if visited[k] {
                    break false;
                }
            };
            if !is_loop || rim.len() < 3 {
                continue;
            }
            let point = |v: u32| split.positions[v as usize];
            let length: f64 = rim
                .iter()
                .map(|&k| (point(borders[k].1) - point(borders[k].0)).norm())
                .sum();
            if length > max_rim {
                continue;
            }
            let centroid = rim
                .iter()
                .fold(Vector3::zeros(), |acc, &k| acc + point(borders[k].0).coords)
                / rim.len() as f64;
            let c = out.positions.len() as u32;
            out.positions.push(Point3::from(centroid));
            out.triangles
                .extend(rim.iter().map(|&k| [borders[k].1, borders[k].0, c]));
            closed += 1;
        }
        if closed == 0 {
            return (self.clone(), 0);
        }
        (out, closed)
    }

    /// Border edges (one face only), directed as their face traverses them.
    pub fn border_edges(&self) -> Vec<(u32, u32)> {
        self.edge_incidence()
            .iter()
            .filter_map(|&[a, b, f, g]| match (f == NO_FACE, g == NO_FACE) {
                (false, true) => Some((a, b)),
                (true, false) => Some((b, a)),
                _ => None,
            })
            .collect()
    }

    /// The mesh with every pinch vertex (more than one border edge leaving it: holes, or a
    /// hole and an outer rim, touching there) split into one vertex per fan of faces around
    /// it (faces sharing an edge through the vertex), so no vertex has more than one rim
    /// leaving it (rims that met there join through its copies). Positions repeat at the
    /// split vertices; faces keep their order.
    pub fn with_pinches_split(&self) -> TriMesh {
        let mut leaving: HashMap<u32, usize> = HashMap::new();
        for (a, _) in self.border_edges() {
            *leaving.entry(a).or_default() += 1;
        }
        let mut pinches: Vec<u32> = leaving
            .into_iter()
            .filter(|&(_, k)| k > 1)
            .map(|(v, _)| v)
            .collect();
        pinches.sort_unstable();
        if pinches.is_empty() {
            return self.clone();
        }
        let mut around: HashMap<u32, Vec<usize>> =
            pinches.iter().map(|&v| (v, Vec::new())).collect();
        for (f, t) in self.triangles.iter().enumerate() {
            for v in t {
                if let Some(faces) = around.get_mut(v) {
                    faces.push(f);
                }
            }
        }
        let mut out = self.clone();
        for v in pinches {
            let faces = &around[&v];
            // Union-find over the faces around `v`: two are in one fan when they share
            // another vertex (then the edge from `v` to it).
            let mut parent: Vec<usize> = (0..faces.len()).collect();
            fn root(parent: &mut [usize], mut k: usize) -> usize {
                while parent[k] != k {
                    parent[k] = parent[parent[k]];
                    k = parent[k];
                }
                k
            }
            let mut first_with: HashMap<u32, usize> = HashMap::new();
            for (k, &f) in faces.iter().enumerate() {
                for &x in &self.triangles[f] {
                    if x == v {
                        continue;
                    }
                    match first_with.get(&x) {
                        Some(&j) => {
                            let (a, b) = (root(&mut parent, j), root(&mut parent, k));
                            parent[a.max(b)] = a.min(b);
                        }
                        None => {
                            first_with.insert(x, k);
                        }
                    }
                }
            }
            // The fan of the first face keeps `v`; every other fan gets a copy.
            let mut copy_of: HashMap<usize, u32> = HashMap::new();
            let first_root = root(&mut parent, 0);
            for (k, &f) in faces.iter().enumerate() {
                let r = root(&mut parent, k);
                if r == first_root {
                    continue;
                }
                let copy = *copy_of.entry(r).or_insert_with(|| {
                    out.positions.push(self.positions[v as usize]);
                    (out.positions.len() - 1) as u32
                });
                for w in out.triangles[f].iter_mut() {
                    if *w == v {
                        *w = copy;
                    }
                }
            }
        }
        out
    }

    /// Applies `p -> linear * p + offset`; flips winding when the map mirrors.
    pub fn transform_affine(&mut self, linear: &Matrix3, offset: &Vector3) {
        for p in &mut self.positions {
            *p = Point3::from(linear * p.coords + offset);
        }
        if linear.determinant() < 0.0 {
            for t in &mut self.triangles {
                t.swap(1, 2);
            }
        }
    }

    pub fn translated(mut self, offset: Vector3) -> Self {
        for p in &mut self.positions {
            *p += offset;
        }
        self
    }

    pub fn transformed(mut self, linear: &Matrix3, offset: &Vector3) -> Self {
        self.transform_affine(linear, offset);
        self
    }

    /// Appends another mesh (no welding, no boolean: the result may overlap itself).
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }

    /// The mesh with vertices at bit-identical positions made one (the first of each), every
    /// triangle kept in its order with its corners at the same positions; `None` when no two
    /// vertices share a position. A mesh file with per-corner texture coordinates or colours
    /// repeats each vertex once per corner (a glTF or OBJ export of a textured model): its
    /// triangles then share no edge, so it is no closed surface until its vertices are
    /// shared, and its silhouette is filled from every triangle's edges (the hard suite's
    /// textured can rendered 20 times slower than the same can as a scene script).
    pub fn with_coincident_vertices_shared(&self) -> Option<TriMesh> {
        let key = |p: &Point3| (p.x.to_bits(), p.y.to_bits(), p.z.to_bits());
        let mut first: HashMap<(u64, u64, u64), u32> = HashMap::with_capacity(self.positions.len());
        let mut remap = Vec::with_capacity(self.positions.len());
        let mut positions = Vec::new();
        for p in &self.positions {
            let next = positions.len() as u32;
            let j = *first.entry(key(p)).or_insert(next);
            if j == next {
                positions.push(*p);
            }
            remap.push(j);
        }
        if positions.len() == self.positions.len() {
            return None;
        }
        let triangles = self
            .triangles
            .iter()
            .map(|t| t.map(|i| remap.get(i as usize).copied().unwrap_or(i)))
            .collect();
        Some(TriMesh {
            positions,
            triangles,
        })
    }

    /// Merges vertices closer than `tolerance` (grid hashing), drops degenerate triangles
    /// and unused vertices. Keeps the first vertex of each cluster.
    pub fn welded(&self, tolerance: f64) -> TriMesh {
        let inv = 1.0 / tolerance.max(1e-15);
        let key = |p: &Point3| {
            (
                (p.x * inv).round() as i64,
                (p.y * inv).round() as i64,
                (p.z * inv).round() as i64,
            )
        };
        let mut cells: HashMap<(i64, i64, i64), Vec<u32>> = HashMap::new();
        let mut remap = vec![0u32; self.positions.len()];
        let mut out_pos: Vec<Point3> = Vec::new();
        for (i, p) in self.positions.iter().enumerate() {
            let (kx, ky, kz) = key(p);
            let mut found = None;
            'search: for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(list) = cells.get(&(kx + dx, ky + dy, kz + dz)) {
                            for &j in list {
                                if (out_pos[j as usize] - p).norm() <= tolerance {
                                    found = Some(j);
                                    break 'search;
                                }
                            }
                        }
                    }
                }
            }
            let j = match found {
                Some(j) => j,
                None => {
                    let j = out_pos.len() as u32;
                    out_pos.push(*p);
                    cells.entry((kx, ky, kz)).or_default().push(j);
                    j
                }
            };
            remap[i] = j;
        }
        let triangles: Vec<[u32; 3]> = self
            .triangles
            .iter()
            .map(|t| {
                [
                    remap[t[0] as usize],
                    remap[t[1] as usize],
                    remap[t[2] as usize],
                ]
            })
            .filter(|t| t[0] != t[1] && t[1] != t[2] && t[0] != t[2])
            .collect();
        TriMesh::new(out_pos, triangles).compacted()
    }

    /// Drops vertices that no triangle uses, keeping order.
    pub fn compacted(self) -> TriMesh {
        let mut used = vec![u32::MAX; self.positions.len()];
        let mut positions = Vec::new();
        let mut triangles = Vec::with_capacity(self.triangles.len());
        for t in &self.triangles {
            let mut nt = [0u32; 3];
            for k in 0..3 {
                let i = t[k] as usize;
                if used[i] == u32::MAX {
                    used[i] = positions.len() as u32;
                    positions.push(self.positions[i]);
                }
                nt[k] = used[i];
            }
            triangles.push(nt);
        }
        TriMesh {
            positions,
            triangles,
        }
    }

    /// True when every coordinate is finite.
    pub fn is_finite(&self) -> bool {
        self.positions
            .iter()
            .all(|p| p.coords.iter().all(|c| c.is_finite()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra() -> TriMesh {
        TriMesh::new(
            vec![
                Point3::new(0.0, 0.0, 0.0),
                Point3::new(1.0, 0.0, 0.0),
                Point3::new(0.0, 1.0, 0.0),
                Point3::new(0.0, 0.0, 1.0),
            ],
            vec![[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]],
        )
    }

    #[test]
    fn tetra_volume_and_watertight() {
        let t = tetra();
        assert!((t.volume() - 1.0 / 6.0).abs() < 1e-12);
        assert!(t.is_watertight());
        let mut open = t.clone();
        open.triangles.pop();
        assert!(!open.is_watertight());
    }

    #[test]
    fn mirror_keeps_volume_positive() {
        let m = tetra().transformed(
            &Matrix3::from_diagonal(&Vector3::new(-1.0, 1.0, 1.0)),
            &Vector3::zeros(),
        );
        assert!((m.volume() - 1.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn weld_merges_duplicates() {
        let mut a = tetra();
        let b = tetra();
        a.append(&b);
        let w = a.welded(1e-9);
        assert_eq!(w.positions.len(), 4);
        assert_eq!(w.triangles.len(), 8);
    }
}
