//! Primitive solids, meshed watertight and oriented outward, in their own frame: centred at
//! the origin with Z as the axis of symmetry unless a primitive says otherwise.
//!
//! Every size is a full extent or a radius in canonical units; segment counts are bounded
//! so that a model-written script cannot ask for an unbounded mesh.

use crate::hull::convex_hull;
use crate::mesh::TriMesh;
use crate::{GeomError, Point3, Result};
use std::f64::consts::{PI, TAU};

pub const MAX_SEGMENTS: u32 = 1024;

fn invalid(primitive: &str, reason: impl Into<String>) -> GeomError {
    GeomError::InvalidArgument {
        primitive: primitive.into(),
        reason: reason.into(),
    }
}

fn positive(primitive: &str, name: &str, v: f64) -> Result<()> {
    if !(v.is_finite() && v > 0.0) {
        return Err(invalid(
            primitive,
            format!("`{name}` must be a positive finite number, got {v}"),
        ));
    }
    Ok(())
}

fn non_negative(primitive: &str, name: &str, v: f64) -> Result<()> {
    if !(v.is_finite() && v >= 0.0) {
        return Err(invalid(
            primitive,
            format!("`{name}` must be a finite number ≥ 0, got {v}"),
        ));
    }
    Ok(())
}

fn segments(primitive: &str, name: &str, n: i64, min: u32) -> Result<u32> {
    if n < min as i64 || n > MAX_SEGMENTS as i64 {
        return Err(invalid(
            primitive,
            format!("`{name}` must be between {min} and {MAX_SEGMENTS}, got {n}"),
        ));
    }
    Ok(n as u32)
}

/// Flips every triangle when the signed volume is negative.
fn orient_outward(mut m: TriMesh) -> TriMesh {
    if m.volume() < 0.0 {
        for t in &mut m.triangles {
            t.swap(1, 2);
        }
    }
    m
}

/// An axis-aligned box with full extents `size_x × size_y × size_z`.
pub fn cuboid(size_x: f64, size_y: f64, size_z: f64) -> Result<TriMesh> {
    for (n, v) in [("size_x", size_x), ("size_y", size_y), ("size_z", size_z)] {
        positive("box", n, v)?;
    }
    let (hx, hy, hz) = (size_x / 2.0, size_y / 2.0, size_z / 2.0);
    let positions: Vec<Point3> = (0..8)
        .map(|i| {
            Point3::new(
                if i & 1 == 0 { -hx } else { hx },
                if i & 2 == 0 { -hy } else { hy },
                if i & 4 == 0 { -hz } else { hz },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    Ok(orient_outward(TriMesh::new(positions, triangles)))
}

/// A box whose edges are rounded with `radius` (`segments` = 1 gives a chamfer).
pub fn bevelled_box(
    size_x: f64,
    size_y: f64,
    size_z: f64,
    radius: f64,
    segs: i64,
) -> Result<TriMesh> {
    for (n, v) in [("size_x", size_x), ("size_y", size_y), ("size_z", size_z)] {
        positive("box", n, v)?;
    }
    non_negative("box", "bevel", radius)?;
    let half_min = size_x.min(size_y).min(size_z) / 2.0;
    if radius >= half_min {
        return Err(invalid(
            "box",
            format!("bevel {radius} must be smaller than half the smallest side ({half_min})"),
        ));
    }
    if radius == 0.0 {
        return cuboid(size_x, size_y, size_z);
    }
    let segs = segments("box", "segments", segs, 1)?;
    // The rounded box is the hull of eight corner spheres of the inner box.
    let inner = [
        size_x / 2.0 - radius,
        size_y / 2.0 - radius,
        size_z / 2.0 - radius,
    ];
    let mut pts = Vec::new();
    for sx in [-1.0, 1.0] {
        for sy in [-1.0, 1.0] {
            for sz in [-1.0, 1.0] {
                for i in 0..=segs {
                    let theta = (PI / 2.0) * i as f64 / segs as f64;
                    for j in 0..=segs {
                        let phi = (PI / 2.0) * j as f64 / segs as f64;
                        let d = [
                            theta.sin() * phi.cos(),
                            theta.sin() * phi.sin(),
                            theta.cos(),
                        ];
                        pts.push(Point3::new(
                            sx * (inner[0] + radius * d[0]),
                            sy * (inner[1] + radius * d[1]),
                            sz * (inner[2] + radius * d[2]),
                        ));
                    }
                }
            }
        }
    }
    let mut h = convex_hull(&pts)?;
    h = h.welded(radius * 1e-6);
    Ok(h)
}

/// Revolves a profile of `(radius, z)` points about +Z. Points with radius 0 become poles;
/// an open profile whose ends are off the axis is closed with flat caps; a profile whose
/// first and last points coincide is a closed loop (a ring, no caps).
pub fn lathe(profile: &[(f64, f64)], segs: i64) -> Result<TriMesh> {
    lathe_named("lathe", profile, segs)
}

fn lathe_named(name: &str, profile: &[(f64, f64)], segs: i64) -> Result<TriMesh> {
    let n = segments(name, "segments", segs, 3)? as usize;
    let mut prof: Vec<(f64, f64)> = Vec::with_capacity(profile.len());
    for &(r, z) in profile {
        if !(r.is_finite() && z.is_finite()) || r < 0.0 {
            return Err(invalid(
                name,
                format!("profile point ({r}, {z}) must be finite with radius ≥ 0"),
            ));
        }
        if prof
            .last()
            .is_some_and(|&(pr, pz)| (pr - r).abs() < 1e-12 && (pz - z).abs() < 1e-12)
        {
            continue;
        }
        prof.push((r, z));
    }
    let closed = prof.len() > 2 && {
        let (a, b) = (prof[0], prof[prof.len() - 1]);
        (a.0 - b.0).abs() < 1e-12 && (a.1 - b.1).abs() < 1e-12
    };
    if closed {
        prof.pop();
    }
    if prof.len() < 2 || (closed && prof.len() < 3) {
        return Err(invalid(
            name,
            "profile needs at least 2 distinct points (3 for a closed loop)",
        ));
    }
    let pole = |r: f64| r < 1e-12;
    if closed && prof.iter().any(|&(r, _)| pole(r)) {
        return Err(invalid(
            name,
            "a closed profile loop must stay off the axis (radius > 0)",
        ));
    }
    let mut positions = Vec::new();
    // For each profile point, its vertex indices (one for a pole, n for a ring).
    let mut rings: Vec<Vec<u32>> = Vec::new();
    for &(r, z) in &prof {
        let start = positions.len() as u32;
        if pole(r) {
            positions.push(Point3::new(0.0, 0.0, z));
            rings.push(vec![start]);
        } else {
            for k in 0..n {
                let a = TAU * k as f64 / n as f64;
                positions.push(Point3::new(r * a.cos(), r * a.sin(), z));
            }
            rings.push((start..start + n as u32).collect());
        }
    }
    let mut triangles = Vec::new();
    let connect = |a: &Vec<u32>, b: &Vec<u32>, triangles: &mut Vec<[u32; 3]>| -> Result<()> {
        match (a.len(), b.len()) {
            (1, 1) => Err(invalid(name, "two consecutive profile points on the axis")),
            (1, _) => {
                for k in 0..n {
                    triangles.push([a[0], b[(k + 1) % n], b[k]]);
                }
                Ok(())
            }
            (_, 1) => {
                for k in 0..n {
                    triangles.push([a[k], a[(k + 1) % n], b[0]]);
                }
                Ok(())
            }
            _ => {
                for k in 0..n {
                    let k1 = (k + 1) % n;
                    triangles.push([a[k], a[k1], b[k1]]);
                    triangles.push([a[k], b[k1], b[k]]);
                }
                Ok(())
            }
        }
    };
    for i in 0..prof.len() - 1 {
        connect(&rings[i], &rings[i + 1], &mut triangles)?;
    }
    if closed {
        connect(&rings[prof.len() - 1], &rings[0], &mut triangles)?;
    } else {
        for (idx, at_start) in [(0usize, true), (prof.len() - 1, false)] {
            if rings[idx].len() > 1 {
                let centre = positions.len() as u32;
                positions.push(Point3::new(0.0, 0.0, prof[idx].1));
                let ring = rings[idx].clone();
                for k in 0..n {
                    if at_start {
                        triangles.push([centre, ring[(k + 1) % n], ring[k]]);
                    } else {
                        triangles.push([ring[k], ring[(k + 1) % n], centre]);
                    }
                }
            }
        }
    }
    let mesh = orient_outward(TriMesh::new(positions, triangles));
    if mesh.volume().abs() < 1e-15 {
        return Err(invalid(name, "the profile encloses no volume"));
    }
    Ok(mesh)
}

/// A cylinder of `radius` and full `height` along Z.
pub fn cylinder(radius: f64, height: f64, segs: i64) -> Result<TriMesh> {
    positive("cylinder", "radius", radius)?;
    positive("cylinder", "height", height)?;
    let h = height / 2.0;
    lathe_named(
        "cylinder",
        &[(0.0, -h), (radius, -h), (radius, h), (0.0, h)],
        segs,
    )
}

/// A pie-slice prism along Z centred at the origin: the sector of a disc of `radius` from
/// −`angle_deg`/2 to +`angle_deg`/2 about +X (0 < angle < 360), `height` tall, the arc in
/// `segs` pieces. With `intersection` it cuts a part of a turn from a solid: a label over 195°
/// of a can's side is `intersection(sleeve, sector(1, 1, 195))`.
pub fn sector(radius: f64, height: f64, angle_deg: f64, segs: i64) -> Result<TriMesh> {
    positive("sector", "radius", radius)?;
    positive("sector", "height", height)?;
    if !(angle_deg.is_finite() && angle_deg > 0.0 && angle_deg < 360.0) {
        return Err(invalid(
            "sector",
            format!("`angle_deg` must lie strictly between 0 and 360, got {angle_deg}"),
        ));
    }
    let n = segments("sector", "segments", segs, 1)? as usize;
    let half = angle_deg.to_radians() / 2.0;
    let mut outline = vec![(0.0, 0.0)];
    outline.extend((0..=n).map(|k| {
        let t = -half + 2.0 * half * k as f64 / n as f64;
        (radius * t.cos(), radius * t.sin())
    }));
    extrude(&outline, &[], height)
}

/// A truncated cone: `radius_bottom` at z = −height/2, `radius_top` at +height/2 (0 for a point).
pub fn cone(radius_bottom: f64, radius_top: f64, height: f64, segs: i64) -> Result<TriMesh> {
    non_negative("cone", "radius_bottom", radius_bottom)?;
    non_negative("cone", "radius_top", radius_top)?;
    positive("cone", "height", height)?;
    if radius_bottom == 0.0 && radius_top == 0.0 {
        return Err(invalid("cone", "at least one radius must be positive"));
    }
    let h = height / 2.0;
    lathe_named(
        "cone",
        &[(0.0, -h), (radius_bottom, -h), (radius_top, h), (0.0, h)],
        segs,
    )
}

/// A UV sphere with `segments` around Z and `rings` from pole to pole.
pub fn uv_sphere(radius: f64, segs: i64, rings: i64) -> Result<TriMesh> {
    positive("sphere", "radius", radius)?;
    let rings = segments("sphere", "rings", rings, 2)?;
    let profile: Vec<(f64, f64)> = (0..=rings)
        .map(|i| {
            let a = -PI / 2.0 + PI * i as f64 / rings as f64;
            (
                if i == 0 || i == rings {
                    0.0
                } else {
                    radius * a.cos()
                },
                radius * a.sin(),
            )
        })
        .collect();
    lathe_named("sphere", &profile, segs)
}

/// A capsule along Z: a cylinder of `length` between the centres of two hemispheres.
pub fn capsule(radius: f64, length: f64, segs: i64) -> Result<TriMesh> {
    positive("capsule", "radius", radius)?;
    non_negative("capsule", "length", length)?;
    let quarter = (segments("capsule", "segments", segs, 4)? / 4).max(2);
    let mut profile = Vec::new();
    for i in 0..=quarter {
        let a = -PI / 2.0 + (PI / 2.0) * i as f64 / quarter as f64;
        profile.push((
            if i == 0 { 0.0 } else { radius * a.cos() },
            radius * a.sin() - length / 2.0,
        ));
    }
    for i in 0..=quarter {
        let a = (PI / 2.0) * i as f64 / quarter as f64;
        profile.push((
            if i == quarter { 0.0 } else { radius * a.cos() },
            radius * a.sin() + length / 2.0,
        ));
    }
    lathe_named("capsule", &profile, segs)
}

/// An ico sphere: an icosahedron subdivided `subdivisions` times and pushed onto the sphere.
pub fn ico_sphere(radius: f64, subdivisions: i64) -> Result<TriMesh> {
    positive("ico_sphere", "radius", radius)?;
    if !(0..=6).contains(&subdivisions) {
        return Err(invalid(
            "ico_sphere",
            format!("`subdivisions` must be between 0 and 6, got {subdivisions}"),
        ));
    }
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut positions: Vec<Point3> = [
        (-1.0, t, 0.0),
        (1.0, t, 0.0),
        (-1.0, -t, 0.0),
        (1.0, -t, 0.0),
        (0.0, -1.0, t),
        (0.0, 1.0, t),
        (0.0, -1.0, -t),
        (0.0, 1.0, -t),
        (t, 0.0, -1.0),
        (t, 0.0, 1.0),
        (-t, 0.0, -1.0),
        (-t, 0.0, 1.0),
    ]
    .iter()
    .map(|&(x, y, z)| Point3::from(nalgebra::Vector3::new(x, y, z).normalize()))
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoint = std::collections::HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Point3>| -> u32 {
            let key = (a.min(b), a.max(b));
            *midpoint.entry(key).or_insert_with(|| {
                let m = (positions[a as usize].coords + positions[b as usize].coords).normalize();
                positions.push(Point3::from(m));
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(triangles.len() * 4);
        for [a, b, c] in triangles {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        triangles = next;
    }
    for p in &mut positions {
        *p = Point3::from(p.coords * radius);
    }
    Ok(orient_outward(TriMesh::new(positions, triangles)))
}

/// A torus around Z in the XY plane: `major_radius` to the tube centre, `minor_radius` of the tube.
pub fn torus(
    major_radius: f64,
    minor_radius: f64,
    major_segs: i64,
    minor_segs: i64,
) -> Result<TriMesh> {
    positive("torus", "major_radius", major_radius)?;
    positive("torus", "minor_radius", minor_radius)?;
    if minor_radius >= major_radius {
        return Err(invalid(
            "torus",
            format!("minor_radius {minor_radius} must be smaller than major_radius {major_radius}"),
        ));
    }
    let m = segments("torus", "minor_segments", minor_segs, 3)?;
    let profile: Vec<(f64, f64)> = (0..=m)
        .map(|i| {
            let a = TAU * i as f64 / m as f64;
            if i == m {
                (major_radius + minor_radius, 0.0)
            } else {
                (
                    major_radius + minor_radius * a.cos(),
                    minor_radius * a.sin(),
                )
            }
        })
        .collect();
    lathe_named("torus", &profile, major_segs)
}

/// A zero-thickness rectangle `size_x × size_y` in the XY plane, visible from both sides.
/// An open surface: it encloses no volume and is not watertight.
pub fn plane(size_x: f64, size_y: f64) -> Result<TriMesh> {
    positive("plane", "size_x", size_x)?;
    positive("plane", "size_y", size_y)?;
    let (hx, hy) = (size_x / 2.0, size_y / 2.0);
    let positions = vec![
        Point3::new(-hx, -hy, 0.0),
        Point3::new(hx, -hy, 0.0),
        Point3::new(hx, hy, 0.0),
        Point3::new(-hx, hy, 0.0),
    ];
    Ok(TriMesh::new(
        positions,
        vec![[0, 1, 2], [0, 2, 3], [0, 2, 1], [0, 3, 2]],
    ))
}

/// A zero-thickness disc of `radius` in the XY plane, visible from both sides.
pub fn disc(radius: f64, segs: i64) -> Result<TriMesh> {
    positive("disc", "radius", radius)?;
    let n = segments("disc", "segments", segs, 3)?;
    let mut positions = vec![Point3::origin()];
    for k in 0..n {
        let a = TAU * k as f64 / n as f64;
        positions.push(Point3::new(radius * a.cos(), radius * a.sin(), 0.0));
    }
    let mut triangles = Vec::new();
    for k in 0..n {
        let (a, b) = (1 + k, 1 + (k + 1) % n);
        triangles.push([0, a, b]);
        triangles.push([0, b, a]);
    }
    Ok(TriMesh::new(positions, triangles))
}

/// A wedge: footprint `size_x × size_y`, full height `size_z` at −Y sloping to zero at +Y.
pub fn wedge(size_x: f64, size_y: f64, size_z: f64) -> Result<TriMesh> {
    for (n, v) in [("size_x", size_x), ("size_y", size_y), ("size_z", size_z)] {
        positive("wedge", n, v)?;
    }
    let (hx, hy, hz) = (size_x / 2.0, size_y / 2.0, size_z / 2.0);
    let pts = [
        Point3::new(-hx, -hy, -hz),
        Point3::new(hx, -hy, -hz),
        Point3::new(-hx, hy, -hz),
        Point3::new(hx, hy, -hz),
        Point3::new(-hx, -hy, hz),
        Point3::new(hx, -hy, hz),
    ];
    convex_hull(&pts)
}

/// Extrudes a polygon in the XY plane (outline plus optional holes, any orientation) to a
/// prism of full `height` along Z, centred on z = 0.
pub fn extrude(outline: &[(f64, f64)], holes: &[Vec<(f64, f64)>], height: f64) -> Result<TriMesh> {
    positive("extrude", "height", height)?;
    let signed_area = |l: &[(f64, f64)]| -> f64 {
        (0..l.len())
            .map(|i| {
                let (a, b) = (l[i], l[(i + 1) % l.len()]);
                a.0 * b.1 - b.0 * a.1
            })
            .sum::<f64>()
            / 2.0
    };
    let mut loops: Vec<Vec<(f64, f64)>> = Vec::new();
    for (li, l) in std::iter::once(outline)
        .chain(holes.iter().map(|h| h.as_slice()))
        .enumerate()
    {
        let mut l: Vec<(f64, f64)> = l.to_vec();
        if l.len() > 1 && l.first() == l.last() {
            l.pop();
        }
        let what = if li == 0 {
            "outline".to_string()
        } else {
            format!("hole {}", li - 1)
        };
        if l.len() < 3 {
            return Err(invalid(
                "extrude",
                format!("{what} needs at least 3 points, got {}", l.len()),
            ));
        }
        if l.iter().any(|p| !(p.0.is_finite() && p.1.is_finite())) {
            return Err(invalid("extrude", format!("{what} has a non-finite point")));
        }
        let area = signed_area(&l);
        if area.abs() < 1e-14 {
            return Err(invalid("extrude", format!("{what} has zero area")));
        }
        // Outline counter-clockwise, holes clockwise, seen from +Z.
        if (li == 0) != (area > 0.0) {
            l.reverse();
        }
        loops.push(l);
    }
    let flat: Vec<[f64; 2]> = loops.iter().flatten().map(|&(x, y)| [x, y]).collect();
    let mut hole_starts = Vec::new();
    let mut acc = loops[0].len();
    for l in &loops[1..] {
        hole_starts.push(acc as u32);
        acc += l.len();
    }
    let mut tris: Vec<u32> = Vec::new();
    earcut::Earcut::new().earcut(flat.iter().copied(), &hole_starts, &mut tris);
    if tris.is_empty() {
        return Err(invalid("extrude", "the polygon could not be triangulated (self-intersecting outline or holes outside it?)"));
    }
    let n = flat.len() as u32;
    let h = height / 2.0;
    let mut positions: Vec<Point3> = flat.iter().map(|p| Point3::new(p[0], p[1], -h)).collect();
    positions.extend(flat.iter().map(|p| Point3::new(p[0], p[1], h)));
    let mut triangles = Vec::new();
    for t in tris.chunks_exact(3) {
        let (a, b, c) = (t[0], t[1], t[2]);
        // Earcut's winding is not specified: orient caps by their 2-D signed area.
        let pa = flat[a as usize];
        let pb = flat[b as usize];
        let pc = flat[c as usize];
        let ccw = (pb[0] - pa[0]) * (pc[1] - pa[1]) - (pb[1] - pa[1]) * (pc[0] - pa[0]) > 0.0;
        let (b, c) = if ccw { (b, c) } else { (c, b) };
        triangles.push([a + n, b + n, c + n]);
        triangles.push([a, c, b]);
    }
    let mut start = 0u32;
    for l in &loops {
        let len = l.len() as u32;
        for i in 0..len {
            let (a, b) = (start + i, start + (i + 1) % len);
            triangles.push([a, b, b + n]);
            triangles.push([a, b + n, a + n]);
        }
        start += len;
    }
    Ok(TriMesh::new(positions, triangles))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: f64, b: f64, rel: f64) -> bool {
        (a - b).abs() <= rel * b.abs().max(1e-12)
    }

    fn check(m: &TriMesh, volume: f64, area: f64, rel: f64) {
        assert!(m.is_watertight(), "not watertight");
        assert!(
            close(m.volume(), volume, rel),
            "volume {} vs {}",
            m.volume(),
            volume
        );
        assert!(close(m.area(), area, rel), "area {} vs {}", m.area(), area);
    }

    #[test]
    fn a_sector_is_the_share_of_the_disc_its_angle_says_and_refuses_a_full_turn() {
        for (angle, segs) in [(90.0, 12), (195.0, 48), (300.0, 60)] {
            let m = sector(0.5, 0.2, angle, segs).expect("sector");
            assert!(m.is_watertight(), "{angle}");
            // The polygon inscribed in the arc: n triangles of the arc's chords.
            let piece = angle.to_radians() / segs as f64;
            let area = 0.5 * 0.25 * piece.sin() * segs as f64;
            assert!(
                close(m.volume(), area * 0.2, 1e-9),
                "{angle}: {}",
                m.volume()
            );
        }
        for bad in [0.0, 360.0, -10.0, f64::NAN] {
            assert!(sector(0.5, 0.2, bad, 12).is_err(), "{bad}");
        }
        assert!(sector(-0.5, 0.2, 90.0, 12).is_err());
    }

    #[test]
    fn box_is_exact() {
        check(&cuboid(1.0, 2.0, 3.0).expect("box"), 6.0, 22.0, 1e-12);
    }

    #[test]
    fn bevelled_box_volume() {
        let (a, b, c, r) = (1.0, 0.8, 0.6, 0.1);
        let m = bevelled_box(a, b, c, r, 8).expect("box");
        let (ia, ib, ic) = (a - 2.0 * r, b - 2.0 * r, c - 2.0 * r);
        let v = ia * ib * ic
            + 2.0 * r * (ia * ib + ib * ic + ia * ic)
            + PI * r * r * (ia + ib + ic)
            + 4.0 / 3.0 * PI * r * r * r;
        let area =
            2.0 * (ia * ib + ib * ic + ia * ic) + 2.0 * PI * r * (ia + ib + ic) + 4.0 * PI * r * r;
        check(&m, v, area, 0.01);
    }

    #[test]
    fn round_primitives_match_analytic_volume_and_area() {
        check(
            &cylinder(0.5, 2.0, 128).expect("c"),
            PI * 0.25 * 2.0,
            2.0 * PI * 0.5 * 2.0 + 2.0 * PI * 0.25,
            0.002,
        );
        let (r1, r2, h) = (0.5f64, 0.2f64, 1.0f64);
        let slant = ((r1 - r2) * (r1 - r2) + h * h).sqrt();
        check(
            &cone(r1, r2, h, 128).expect("cone"),
            PI * h / 3.0 * (r1 * r1 + r1 * r2 + r2 * r2),
            PI * (r1 + r2) * slant + PI * (r1 * r1 + r2 * r2),
            0.002,
        );
        check(
            &cone(0.5, 0.0, 1.0, 128).expect("cone"),
            PI * 0.25 / 3.0,
            PI * 0.5 * (0.25f64 + 1.0).sqrt() + PI * 0.25,
            0.002,
        );
        check(
            &uv_sphere(0.5, 128, 64).expect("s"),
            4.0 / 3.0 * PI * 0.125,
            4.0 * PI * 0.25,
            0.002,
        );
        check(
            &ico_sphere(0.5, 5).expect("s"),
            4.0 / 3.0 * PI * 0.125,
            4.0 * PI * 0.25,
            0.002,
        );
        check(
            &torus(0.4, 0.1, 128, 64).expect("t"),
            2.0 * PI * PI * 0.4 * 0.01,
            4.0 * PI * PI * 0.4 * 0.1,
            0.003,
        );
        check(
            &capsule(0.2, 0.6, 128).expect("c"),
            PI * 0.04 * 0.6 + 4.0 / 3.0 * PI * 0.008,
            2.0 * PI * 0.2 * 0.6 + 4.0 * PI * 0.04,
            0.003,
        );
        check(
            &wedge(1.0, 2.0, 3.0).expect("w"),
            3.0,
            2.0 + 3.0 + 2.0 * 3.0 / 2.0 * 2.0 + (4.0f64 + 9.0).sqrt(),
            1e-9,
        );
    }

    #[test]
    fn flat_primitives_are_two_sided() {
        // Open surfaces: both sides are meshed, so the area counts each side once.
        let p = plane(1.0, 2.0).expect("plane");
        assert!(close(p.area(), 4.0, 1e-12));
        assert!(p.volume().abs() < 1e-12);
        let d = disc(0.5, 256).expect("disc");
        assert!(close(d.area(), 2.0 * PI * 0.25, 0.001));
    }

    #[test]
    fn extrusion_with_hole() {
        let outline = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)];
        let hole = vec![(-0.5, -0.5), (-0.5, 0.5), (0.5, 0.5), (0.5, -0.5)];
        let m = extrude(&outline, std::slice::from_ref(&hole), 0.5).expect("extrude");
        check(&m, 3.0 * 0.5, 2.0 * 3.0 + 0.5 * 8.0 + 0.5 * 4.0, 1e-9);
        // Orientation of the input does not matter.
        let mut rev = outline.to_vec();
        rev.reverse();
        let mut hrev = hole;
        hrev.reverse();
        check(
            &extrude(&rev, &[hrev], 0.5).expect("extrude"),
            1.5,
            12.0,
            1e-9,
        );
    }

    #[test]
    fn lathe_closed_loop_is_a_ring() {
        // A square cross-section revolved: a washer.
        let m = lathe(
            &[
                (0.3, -0.1),
                (0.5, -0.1),
                (0.5, 0.1),
                (0.3, 0.1),
                (0.3, -0.1),
            ],
            256,
        )
        .expect("ring");
        check(
            &m,
            PI * (0.25 - 0.09) * 0.2,
            2.0 * PI * (0.25 - 0.09) + 2.0 * PI * 0.8 * 0.2,
            0.002,
        );
    }

    #[test]
    fn bad_arguments_name_the_parameter() {
        let e = cylinder(-1.0, 1.0, 32).expect_err("negative radius");
        assert!(e.to_string().contains("`radius`"), "{e}");
        let e = cylinder(1.0, 1.0, 1_000_000).expect_err("huge");
        assert!(e.to_string().contains("segments"), "{e}");
        assert!(torus(0.1, 0.2, 32, 16).is_err());
        assert!(bevelled_box(1.0, 1.0, 1.0, 0.6, 4).is_err());
    }
}
