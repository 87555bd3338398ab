//! Mesh files: OBJ, STL (ASCII and binary), PLY (ASCII and binary) and GLB read into one
//! triangle mesh in the file's own frame; OBJ written for exports. GLB files are Y-up and
//! are converted to the canonical Z-up frame (`(x, y, z)_gltf → (x, −z, y)`).

use crate::{read_bytes, DataError, Result};
use agentstar_geom::{Matrix4, Point3, TriMesh};
use std::path::Path;

/// The extensions [`load_mesh`] understands.
pub const MESH_EXTENSIONS: [&str; 4] = ["obj", "stl", "ply", "glb"];

/// Loads a mesh file by its extension and checks it (non-empty, finite, indices in range).
pub fn load_mesh(path: &Path) -> Result<TriMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let bytes = read_bytes(path)?;
    let mesh = match ext.as_str() {
        "obj" => parse_obj(&bytes),
        "stl" => parse_stl(&bytes),
        "ply" => parse_ply(&bytes),
        "glb" => parse_glb(&bytes).map(|parts| {
            let mut m = TriMesh::default();
            for (_, p) in parts {
                m.append(&p);
            }
            m
        }),
        "" => Err("has no file extension; a mesh file is .obj, .stl, .ply or .glb".into()),
        other => Err(format!(
            "unsupported mesh format `.{other}`; use one of .obj, .stl, .ply, .glb"
        )),
    }
    .map_err(|m| DataError::invalid(path, m))?;
    check(&mesh).map_err(|m| DataError::invalid(path, m))?;
    Ok(mesh)
}

fn check(mesh: &TriMesh) -> Result<(), String> {
    if mesh.triangles.is_empty() {
        return Err("the mesh has no triangles".into());
    }
    if !mesh.is_finite() {
        return Err("a vertex has a non-finite coordinate".into());
    }
    let n = mesh.positions.len() as u32;
    if let Some(t) = mesh.triangles.iter().find(|t| t.iter().any(|&i| i >= n)) {
        return Err(format!(
            "a face refers to vertex {} but there are only {n}",
            t.iter().max().copied().unwrap_or(0) + 1
        ));
    }
    Ok(())
}

pub fn parse_obj(bytes: &[u8]) -> Result<TriMesh, String> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let mut reader = std::io::BufReader::new(bytes);
    let (models, _) =
        tobj::load_obj_buf(&mut reader, &opts, |_| Err(tobj::LoadError::OpenFileFailed))
            .map_err(|e| format!("not a valid OBJ file: {e}"))?;
    let mut mesh = TriMesh::default();
    for m in models {
        let base = mesh.positions.len() as u32;
        let p = &m.mesh.positions;
        mesh.positions.extend(
            p.chunks_exact(3)
                .map(|c| Point3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
        );
        mesh.triangles.extend(
            m.mesh
                .indices
                .chunks_exact(3)
                .map(|t| [t[0] + base, t[1] + base, t[2] + base]),
        );
    }
    Ok(mesh)
}

pub fn parse_stl(bytes: &[u8]) -> Result<TriMesh, String> {
    let mut cursor = std::io::Cursor::new(bytes);
    let stl = stl_io::read_stl(&mut cursor).map_err(|e| format!("not a valid STL file: {e}"))?;
    Ok(TriMesh::new(
        stl.vertices
            .iter()
            .map(|v| Point3::new(v[0] as f64, v[1] as f64, v[2] as f64))
            .collect(),
        stl.faces
            .iter()
            .map(|f| {
                [
                    f.vertices[0] as u32,
                    f.vertices[1] as u32,
                    f.vertices[2] as u32,
                ]
            })
            .collect(),
    ))
}

#[derive(Clone, Copy, PartialEq)]
enum PlyFormat {
    Ascii,
    Little,
    Big,
}

fn ply_size(ty: &str) -> Option<usize> {
    Some(match ty {
        "char" | "uchar" | "int8" | "uint8" => 1,
        "short" | "ushort" | "int16" | "uint16" => 2,
        "int" | "uint" | "float" | "int32" | "uint32" | "float32" => 4,
        "double" | "float64" => 8,
        _ => return None,
    })
}

fn ply_read(ty: &str, b: &[u8], fmt: PlyFormat) -> f64 {
    macro_rules! rd {
        ($t:ty, $n:expr) => {{
            let mut a = [0u8; $n];
            a.copy_from_slice(&b[..$n]);
            if fmt == PlyFormat::Big {
                <$t>::from_be_bytes(a) as f64
            } else {
                <$t>::from_le_bytes(a) as f64
            }
        }};
    }
    match ty {
        "char" | "int8" => b[0] as i8 as f64,
        "uchar" | "uint8" => b[0] as f64,
        "short" | "int16" => rd!(i16, 2),
        "ushort" | "uint16" => rd!(u16, 2),
        "int" | "int32" => rd!(i32, 4),
        "uint" | "uint32" => rd!(u32, 4),
        "float" | "float32" => rd!(f32, 4),
        _ => rd!(f64, 8),
    }
}

/// PLY with a `vertex` element (x, y, z) and a `face` element (a list of indices);
/// other elements and properties are skipped.
pub fn parse_ply(bytes: &[u8]) -> Result<TriMesh, String> {
    let end = bytes
        .windows(10)
        .position(|w| w == b"end_header")
        .ok_or("not a PLY file: no end_header")?;
    let header = std::str::from_utf8(&bytes[..end]).map_err(|_| "PLY header is not text")?;
    let mut body_start = end + 10;
    while body_start < bytes.len() && (bytes[body_start] == b'\r' || bytes[body_start] == b'\n') {
        body_start += 1;
        if bytes[body_start - 1] == b'\n' {
            break;
        }
    }
    let mut lines = header.lines();
    if lines.next().map(str::trim) != Some("ply") {
        return Err("not a PLY file: it must start with `ply`".into());
    }
    let mut fmt = None;
    // (name, count, properties: (name, type, list count type))
    type Property = (String, String, Option<String>);
    let mut elements: Vec<(String, usize, Vec<Property>)> = Vec::new();
    for line in lines {
        let t: Vec<&str> = line.split_whitespace().collect();
        match t.as_slice() {
            ["format", f, ..] => {
                fmt = Some(match *f {
                    "ascii" => PlyFormat::Ascii,
                    "binary_little_endian" => PlyFormat::Little,
                    "binary_big_endian" => PlyFormat::Big,
                    other => return Err(format!("unknown PLY format `{other}`")),
                })
            }
            ["element", name, count] => elements.push((
                name.to_string(),
                count
                    .parse()
                    .map_err(|_| format!("bad element count `{count}`"))?,
                vec![],
            )),
            ["property", "list", ct, it, name] => {
                let e = elements.last_mut().ok_or("property before any element")?;
                e.2.push((name.to_string(), it.to_string(), Some(ct.to_string())));
            }
            ["property", ty, name] => {
                let e = elements.last_mut().ok_or("property before any element")?;
                e.2.push((name.to_string(), ty.to_string(), None));
            }
            _ => {}
        }
    }
    let fmt = fmt.ok_or("PLY header has no format line")?;
    for (_, _, props) in &elements {
        for (name, ty, ct) in props {
            if ply_size(ty).is_none() || ct.as_deref().is_some_and(|c| ply_size(c).is_none()) {
                return Err(format!("PLY property `{name}` has an unknown type"));
            }
        }
    }
    let mut mesh = TriMesh::default();
    let body = &bytes[body_start..];
    let mut tokens = if fmt == PlyFormat::Ascii {
        std::str::from_utf8(body)
            .map_err(|_| "PLY body is not text")?
            .split_whitespace()
    } else {
        "".split_whitespace()
    };
    let mut pos = 0usize;
    let truncated = || "the PLY file ends early".to_string();
    let mut next = |ty: &str, pos: &mut usize| -> Result<f64, String> {
        if fmt == PlyFormat::Ascii {
            tokens
                .next()
                .ok_or_else(truncated)?
                .parse::<f64>()
                .map_err(|e| format!("bad PLY number: {e}"))
        } else {
            let n = ply_size(ty).unwrap_or(1);
            if *pos + n > body.len() {
                return Err(truncated());
            }
            let v = ply_read(ty, &body[*pos..], fmt);
            *pos += n;
            Ok(v)
        }
    };
    for (name, count, props) in &elements {
        // Each entry takes at least one byte (or token): a larger count is a lie that would
        // otherwise loop or allocate for it.
        if *count > body.len() {
            return Err(format!(
                "PLY element `{name}` claims {count} entries, more than the file's {} bytes hold",
                body.len()
            ));
        }
        for _ in 0..*count {
            let mut xyz = [0.0; 3];
            for (pname, ty, list) in props {
                match list {
                    Some(ct) => {
                        let c = next(ct, &mut pos)?;
                        if !(c.is_finite() && c >= 0.0 && c.fract() == 0.0 && c <= 1e6) {
                            return Err(format!("PLY list `{pname}` has a bad length {c}"));
                        }
                        let n = c as usize;
                        let mut idx = Vec::with_capacity(n.min(64));
                        for _ in 0..n {
                            idx.push(next(ty, &mut pos)? as u32);
                        }
                        if name == "face" && (pname == "vertex_indices" || pname == "vertex_index")
                        {
                            for k in 1..n.saturating_sub(1) {
                                mesh.triangles.push([idx[0], idx[k], idx[k + 1]]);
                            }
                        }
                    }
                    None => {
                        let v = next(ty, &mut pos)?;
                        if name == "vertex" {
                            match pname.as_str() {
                                "x" => xyz[0] = v,
                                "y" => xyz[1] = v,
                                "z" => xyz[2] = v,
                                _ => {}
                            }
                        }
                    }
                }
            }
            if name == "vertex" {
                mesh.positions.push(Point3::new(xyz[0], xyz[1], xyz[2]));
            }
        }
    }
    Ok(mesh)
}

/// Reads a binary glTF: one mesh per root node (its subtree merged), named after the node,
/// converted to the canonical Z-up frame. Sorted as in the file.
pub fn parse_glb(bytes: &[u8]) -> Result<Vec<(String, TriMesh)>, String> {
    let y_up_to_z_up = Matrix4::new(
        1.0, 0.0, 0.0, 0.0, 0.0, 0.0, -1.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
    );
    parse_glb_from(bytes, y_up_to_z_up)
}

/// Reads a binary glTF as [`parse_glb`] does but keeps the file's own coordinates (no Y-up
/// to Z-up turn): for datasets whose poses refer to the model as stored (HOT3D).
pub fn parse_glb_file_frame(bytes: &[u8]) -> Result<Vec<(String, TriMesh)>, String> {
    parse_glb_from(bytes, Matrix4::identity())
}

/// Checks an accessor before the `gltf` reader touches it (the reader indexes and asserts on
/// what the file claims): its buffer view lies inside the binary chunk, its elements fit
/// in the view, and its type is what we read.
fn check_accessor(
    acc: &gltf::Accessor,
    blob_len: usize,
    what: &str,
    dims: gltf::accessor::Dimensions,
    types: &[gltf::accessor::DataType],
) -> Result<(), String> {
    let bad = |why: String| Err(format!("accessor {} ({what}): {why}", acc.index()));
    if acc.sparse().is_some() {
        return bad("sparse accessors are not supported".into());
    }
    if acc.dimensions() != dims || !types.contains(&acc.data_type()) {
        return bad(format!(
            "type {:?} {:?} is not the expected {dims:?}",
            acc.dimensions(),
            acc.data_type()
        ));
    }
    let Some(view) = acc.view() else {
        return bad("it has no buffer view".into());
    };
    let buffer = view.buffer();
    if !matches!(buffer.source(), gltf::buffer::Source::Bin) {
        return bad("its buffer is not the GLB's binary chunk".into());
    }
    let view_end = view.offset().checked_add(view.length());
    if buffer.length() > blob_len || view_end.is_none_or(|e| e > buffer.length()) {
        return bad("its buffer view lies outside the binary chunk".into());
    }
    let elem = acc.size();
    let stride = view.stride().unwrap_or(elem);
    if stride < elem {
        return bad(format!(
            "byte stride {stride} is smaller than an element ({elem} bytes)"
        ));
    }
    if acc.count() > 0 {
        let last = (acc.count() - 1)
            .checked_mul(stride)
            .and_then(|v| v.checked_add(acc.offset()))
            .and_then(|v| v.checked_add(elem));
        if last.is_none_or(|l| l > view.length()) {
            return bad(format!(
                "{} elements do not fit in its buffer view of {} bytes",
                acc.count(),
                view.length()
            ));
        }
    }
    Ok(())
}

/// Checks what the `gltf` crate (1.4) trusts and panics on: the GLB header and chunk
/// lengths, and the accessor indices that its validation looks up unchecked.
fn precheck_glb(bytes: &[u8]) -> Result<(), String> {
    let word = |at: usize| -> Option<u32> {
        bytes
            .get(at..at + 4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
    };
    if bytes.get(..4) != Some(b"glTF") {
        return Err("not a GLB file (no `glTF` magic)".into());
    }
    let total = word(8).ok_or("the GLB header is truncated")? as usize;
    if total < 20 || total > bytes.len() {
        return Err(format!(
            "the GLB header gives a length of {total} bytes but the file has {}",
            bytes.len()
        ));
    }
    let json_len = word(12).ok_or("the GLB JSON chunk is truncated")? as usize;
    if word(16) != Some(0x4E4F_534A) || 20usize.saturating_add(json_len) > total {
        return Err("the GLB JSON chunk is malformed".into());
    }
    let json_end = 20 + json_len;
    let bin_at = json_end.div_ceil(4) * 4;
    if bin_at + 8 <= total {
        let bin_len = word(bin_at).unwrap_or(u32::MAX) as usize;
        if (bin_at + 8).saturating_add(bin_len) > total {
            return Err("the GLB binary chunk runs past the end of the file".into());
        }
    }
    let json: serde_json::Value = serde_json::from_slice(&bytes[20..json_end])
        .map_err(|e| format!("the GLB JSON chunk is not JSON: {e}"))?;
    let accessors = json["accessors"].as_array().map_or(0, Vec::len);
    for mesh in json["meshes"].as_array().into_iter().flatten() {
        for prim in mesh["primitives"].as_array().into_iter().flatten() {
            let refs = prim["attributes"]
                .as_object()
                .into_iter()
                .flat_map(|a| a.values())
                .chain(std::iter::once(&prim["indices"]))
                .filter(|v| !v.is_null());
            for r in refs {
                if r.as_u64().is_none_or(|i| i as usize >= accessors) {
                    return Err(format!(
                        "a mesh primitive refers to accessor {r}, but there are {accessors}"
                    ));
                }
            }
        }
    }
    Ok(())
}

fn parse_glb_from(bytes: &[u8], root_from_file: Matrix4) -> Result<Vec<(String, TriMesh)>, String> {
    precheck_glb(bytes).map_err(|e| format!("not a valid GLB file: {e}"))?;
    // The prechecks cover the panics we know of in `gltf`; a reader bug we do not know of
    // is still an error about this file rather than a crash.
    let gltf = std::panic::catch_unwind(|| gltf::Gltf::from_slice(bytes))
        .map_err(|_| "not a valid GLB file: the glTF reader failed on it".to_string())?
        .map_err(|e| format!("not a valid GLB file: {e}"))?;
    let blob = gltf.blob.as_deref();
    let blob_len = blob.map_or(0, <[u8]>::len);
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or("the GLB file has no scene")?;
    let mut parts = Vec::new();
    for (i, root) in scene.nodes().enumerate() {
        let mut mesh = TriMesh::default();
        let mut stack = vec![(root.clone(), root_from_file, 0usize)];
        let mut visited = 0usize;
        while let Some((node, parent, depth)) = stack.pop() {
            // A node graph with a cycle (invalid glTF) would never end.
            visited += 1;
            if depth > 256 || visited > 1_000_000 {
                return Err("the node hierarchy is cyclic or deeper than 256 levels".into());
            }
            let local = Matrix4::from_fn(|r, c| node.transform().matrix()[c][r] as f64);
            let world = parent * local;
            if let Some(m) = node.mesh() {
                for prim in m.primitives() {
                    if prim.mode() != gltf::mesh::Mode::Triangles {
                        continue;
                    }
                    use gltf::accessor::{DataType, Dimensions};
                    if let Some(acc) = prim.get(&gltf::Semantic::Positions) {
                        check_accessor(
                            &acc,
                            blob_len,
                            "positions",
                            Dimensions::Vec3,
                            &[DataType::F32],
                        )?;
                    }
                    if let Some(acc) = prim.indices() {
                        check_accessor(
                            &acc,
                            blob_len,
                            "indices",
                            Dimensions::Scalar,
                            &[DataType::U8, DataType::U16, DataType::U32],
                        )?;
                    }
                    let reader = prim.reader(|b| match b.source() {
                        gltf::buffer::Source::Bin => blob,
                        gltf::buffer::Source::Uri(_) => None,
                    });
                    let Some(positions) = reader.read_positions() else {
                        continue;
                    };
                    let base = mesh.positions.len() as u32;
                    let first_triangle = mesh.triangles.len();
                    let pts: Vec<Point3> = positions
                        .map(|p| {
                            world.transform_point(&Point3::new(
                                p[0] as f64,
                                p[1] as f64,
                                p[2] as f64,
                            ))
                        })
                        .collect();
                    let count = pts.len() as u32;
                    mesh.positions.extend(pts);
                    match reader.read_indices() {
                        Some(ind) => {
                            let ind: Vec<u32> = ind.into_u32().collect();
                            mesh.triangles.extend(ind.chunks_exact(3).map(|t| {
                                // Out-of-range indices are reported by `check`.
                                [
                                    t[0].saturating_add(base),
                                    t[1].saturating_add(base),
                                    t[2].saturating_add(base),
                                ]
                            }));
                        }
                        None => mesh.triangles.extend(
                            (0..count / 3)
                                .map(|k| [base + 3 * k, base + 3 * k + 1, base + 3 * k + 2]),
                        ),
                    }
                    if world.fixed_view::<3, 3>(0, 0).determinant() < 0.0 {
                        for t in mesh.triangles.iter_mut().skip(first_triangle) {
                            t.swap(1, 2);
                        }
                    }
                }
            }
            for c in node.children() {
                stack.push((c, world, depth + 1));
            }
        }
        if !mesh.triangles.is_empty() {
            parts.push((
                root.name()
                    .map(str::to_string)
                    .unwrap_or_else(|| format!("node{i}")),
                mesh,
            ));
        }
    }
    if parts.is_empty() {
        return Err(
            "the GLB file holds no triangle geometry (external buffers are not supported)".into(),
        );
    }
    Ok(parts)
}

/// OBJ text of a mesh (vertices and faces, 1-based).
pub fn obj_text(mesh: &TriMesh, name: &str) -> String {
    let mut s = format!("# agentstar\no {name}\n");
    for p in &mesh.positions {
        s.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    for t in &mesh.triangles {
        s.push_str(&format!("f {} {} {}\n", t[0] + 1, t[1] + 1, t[2] + 1));
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use agentstar_geom::primitives::cuboid;

    #[test]
    fn obj_round_trip() {
        let m = cuboid(1.0, 2.0, 3.0).expect("box");
        let back = parse_obj(obj_text(&m, "box").as_bytes()).expect("parse");
        assert_eq!(back.triangles.len(), 12);
        assert!((back.volume() - 6.0).abs() < 1e-6);
    }

    #[test]
    fn ply_ascii_and_binary() {
        let ascii = "ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nproperty uchar red\nelement face 1\nproperty list uchar int vertex_indices\nend_header\n0 0 0 255\n1 0 0 0\n1 1 0 0\n0 1 0 0\n4 0 1 2 3\n";
        let m = parse_ply(ascii.as_bytes()).expect("ascii");
        assert_eq!((m.positions.len(), m.triangles.len()), (4, 2));
        let mut bin = b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\nelement face 1\nproperty list uchar uint vertex_indices\nend_header\n".to_vec();
        for v in [[0.0f64, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.5]] {
            for c in v {
                bin.extend_from_slice(&c.to_le_bytes());
            }
        }
        bin.push(3);
        for i in [0u32, 1, 2] {
            bin.extend_from_slice(&i.to_le_bytes());
        }
        let m = parse_ply(&bin).expect("binary");
        assert_eq!(m.triangles, vec![[0, 1, 2]]);
        assert_eq!(m.positions[2], Point3::new(0.0, 1.0, 0.5));
        assert!(parse_ply(&bin[..bin.len() - 2])
            .expect_err("truncated")
            .contains("ends early"));
    }

    #[test]
    fn stl_binary() {
        let m = cuboid(1.0, 1.0, 1.0).expect("box");
        let tris: Vec<stl_io::Triangle> = (0..m.triangles.len())
            .map(|i| {
                let [a, b, c] = m.triangle(i);
                let v = |p: Point3| stl_io::Vertex::new([p.x as f32, p.y as f32, p.z as f32]);
                stl_io::Triangle {
                    normal: stl_io::Normal::new([0.0, 0.0, 0.0]),
                    vertices: [v(a), v(b), v(c)],
                }
            })
            .collect();
        let mut buf = Vec::new();
        stl_io::write_stl(&mut buf, tris.iter()).expect("write");
        let back = parse_stl(&buf).expect("parse");
        assert!(back.is_watertight());
        assert!((back.volume() - 1.0).abs() < 1e-6);
    }

    #[test]
    fn corrupt_files_name_the_problem() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("broken.obj");
        std::fs::write(&p, "v 0 0 0\nf 1 2 3\n").expect("write");
        let e = load_mesh(&p).expect_err("bad index");
        assert!(e.to_string().contains("broken.obj"), "{e}");
        let p = dir.path().join("x.fbx");
        std::fs::write(&p, "").expect("write");
        assert!(load_mesh(&p)
            .expect_err("ext")
            .to_string()
            .contains("unsupported mesh format"));
    }
}
