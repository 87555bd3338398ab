//! Mesh files: OBJ, STL (ASCII and binary), PLY (ASCII and binary) and GLB read into one
//! triangle mesh in the file's own frame, with the appearance the file gives it (an OBJ's
//! material library with `Kd` and `map_Kd` over its texture coordinates and its vertex
//! colours; a PLY's vertex colours and texture coordinates with the texture its
//! `comment TextureFile` names; a GLB's materials, see [`crate::glb`]); OBJ written for
//! exports. GLB files are Y-up and are converted to the canonical Z-up frame
//! (`(x, y, z)_gltf → (x, −z, y)`). Texture coordinates are stored with `v` down the image
//! (glTF's convention): OBJ's and PLY's `v` is flipped.

pub use crate::glb::{parse_glb, parse_glb_appearance, parse_glb_file_frame};
use crate::texture::{load_texture, SideFiles};
use crate::{read_bytes, DataError, Result};
use agentstar_geom::{AppearedMesh, Material, Point3, SurfaceAppearance, TriMesh};
use std::cell::RefCell;
use std::path::Path;
use std::sync::Arc;

/// The extensions [`load_mesh`] understands.
pub const MESH_EXTENSIONS: [&str; 4] = ["obj", "stl", "ply", "glb"];

/// Loads a mesh file's geometry by its extension and checks it (non-empty, finite, indices
/// in range); its appearance is not read.
pub fn load_mesh(path: &Path) -> Result<TriMesh> {
    Ok(load_appeared_mesh(path, &SideFiles::none())?.mesh)
}

/// Loads a mesh file with its appearance, its side files (material library, textures)
/// looked up in `files`; a side file that cannot be read is a warning of the result.
pub fn load_appeared_mesh(path: &Path, files: &SideFiles) -> Result<AppearedMesh> {
    let ext = path
        .extension()
        .and_then(|e| e.to_str())
        .unwrap_or("")
        .to_ascii_lowercase();
    let bytes = read_bytes(path)?;
    let loaded = match ext.as_str() {
        "obj" => parse_obj_appearance(&bytes, files),
        "stl" => parse_stl(&bytes).map(AppearedMesh::plain),
        "ply" => parse_ply_appearance(&bytes, files),
        "glb" => parse_glb_appearance(&bytes, files).and_then(merge_nodes),
        "" => Err("has no file extension; a mesh file is .obj, .stl, .ply or .glb".into()),
        other => Err(format!(
            "unsupported mesh format `.{other}`; use one of .obj, .stl, .ply, .glb"
        )),
    }
    .map_err(|m| DataError::invalid(path, m))?;
    check(&loaded.mesh).map_err(|m| DataError::invalid(path, m))?;
    Ok(loaded)
}

/// A GLB's root nodes as one mesh (for a single-part import), their appearances side by
/// side; a node without one gets a plain white material (glTF's default).
fn merge_nodes(nodes: Vec<(String, AppearedMesh)>) -> Result<AppearedMesh, String> {
    let any_surface = nodes.iter().any(|(_, n)| n.surface.is_some());
    let mut out = AppearedMesh::default();
    let mut surface: Option<SurfaceAppearance> = None;
    for (name, node) in nodes {
        if any_surface {
            let own = node.surface.as_deref().cloned().unwrap_or_else(|| {
                SurfaceAppearance::plain(&name, [1.0; 3], node.mesh.triangles.len())
            });
            surface = Some(match surface {
                None => own,
                Some(s) => s.appended(&own).map_err(|e| e.to_string())?,
            });
        }
        out.mesh.append(&node.mesh);
        out.warnings.extend(node.warnings);
    }
    out.surface = surface.map(Arc::new);
    Ok(out)
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
    Ok(parse_obj_appearance(bytes, &SideFiles::none())?.mesh)
}

/// The texture file of an MTL `map_Kd` value: its last word when options (`-s 1 1 1`)
/// come first, else the whole value (a name may hold spaces).
fn map_kd_file(value: &str) -> &str {
    let v = value.trim();
    if v.starts_with('-') {
        v.split_whitespace().last().unwrap_or(v)
    } else {
        v
    }
}

/// An OBJ with its material library (`mtllib`, read through `files`): each face's material
/// (`usemtl`) with `Kd` and `map_Kd`, texture coordinates (`vt`) and vertex colours
/// (`v x y z r g b`).
pub fn parse_obj_appearance(bytes: &[u8], files: &SideFiles) -> Result<AppearedMesh, String> {
    let opts = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let warnings = RefCell::new(Vec::new());
    let mut reader = std::io::BufReader::new(bytes);
    let (models, materials) = tobj::load_obj_buf(&mut reader, &opts, |p| {
        let name = p.to_string_lossy().to_string();
        match files.read(&name) {
            Ok((_, mtl)) => tobj::load_mtl_buf(&mut std::io::BufReader::new(mtl.as_slice()))
                .inspect_err(|e| {
                    warnings.borrow_mut().push(format!(
                        "material library `{name}` does not read ({e}); its parts keep their colour"
                    ));
                }),
            Err(e) => {
                warnings.borrow_mut().push(format!(
                    "material library: {e}; its parts keep their colour"
                ));
                Err(tobj::LoadError::OpenFileFailed)
            }
        }
    })
    .map_err(|e| format!("not a valid OBJ file: {e}"))?;
    let mut warnings = warnings.into_inner();
    let mtl = materials.unwrap_or_default();
    // Our materials: tobj's, each with its texture read once; then a default for faces
    // without one.
    let mut ours: Vec<Material> = Vec::with_capacity(mtl.len() + 1);
    for m in &mtl {
        let color = m.diffuse.unwrap_or([1.0; 3]);
        let texture = m.diffuse_texture.as_deref().and_then(|t| {
            let file = map_kd_file(t);
            load_texture(files, file)
                .map_err(|e| {
                    warnings.push(format!(
                        "material `{}`: map_Kd {e}; it keeps its colour Kd",
                        m.name
                    ))
                })
                .ok()
                .map(Arc::new)
        });
        ours.push(Material {
            name: m.name.clone(),
            color: color.map(|c| c.clamp(0.0, 1.0)),
            texture,
        });
    }
    let default = ours.len();
    ours.push(Material {
        name: "default".into(),
        color: [1.0; 3],
        texture: None,
    });
    let mut mesh = TriMesh::default();
    let mut triangle_material = Vec::new();
    let mut corner_uv = Vec::new();
    let mut corner_color = Vec::new();
    let (mut any_uv, mut any_color, mut any_material) = (false, false, false);
    for m in models {
        let base = mesh.positions.len() as u32;
        let p = &m.mesh.positions;
        mesh.positions.extend(
            p.chunks_exact(3)
                .map(|c| Point3::new(c[0] as f64, c[1] as f64, c[2] as f64)),
        );
        let material = m.mesh.material_id.filter(|&i| i < mtl.len());
        any_material |= material.is_some();
        let texcoords = &m.mesh.texcoords;
        let colors = &m.mesh.vertex_color;
        any_uv |= !texcoords.is_empty();
        any_color |= !colors.is_empty();
        for t in m.mesh.indices.chunks_exact(3) {
            mesh.triangles.push([t[0] + base, t[1] + base, t[2] + base]);
            triangle_material.push(material.unwrap_or(default) as u16);
            corner_uv.push([0, 1, 2].map(|k| {
                let i = t[k] as usize;
                match (texcoords.get(2 * i), texcoords.get(2 * i + 1)) {
                    (Some(&u), Some(&v)) => [u, 1.0 - v],
                    _ => [0.0; 2],
                }
            }));
            corner_color.push([0, 1, 2].map(|k| {
                let i = t[k] as usize;
                colors
                    .get(3 * i..3 * i + 3)
                    .map_or([1.0; 3], |c| [c[0], c[1], c[2]].map(|v| v.clamp(0.0, 1.0)))
            }));
        }
    }
    if ours.len() > usize::from(u16::MAX) {
        return Err(format!("{} materials; at most 65535 are read", ours.len()));
    }
    if !any_uv {
        for m in ours.iter_mut().filter(|m| m.texture.is_some()) {
            warnings.push(format!(
                "material `{}` has a texture (map_Kd) but the OBJ has no texture coordinates (vt); it keeps its colour Kd",
                m.name
            ));
            m.texture = None;
        }
    }
    let surface = if any_material || any_color {
        let any_texture = ours.iter().any(|m| m.texture.is_some());
        Some(Arc::new(
            SurfaceAppearance::new(
                ours,
                triangle_material,
                any_texture.then_some(corner_uv),
                any_color.then_some(corner_color),
            )
            .map_err(|e| e.to_string())?,
        ))
    } else {
        None
    };
    Ok(AppearedMesh {
        mesh,
        surface,
        warnings,
    })
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
    Ok(parse_ply_appearance(bytes, &SideFiles::none())?.mesh)
}

/// A PLY vertex colour component as a display value in [0, 1]: integers over their type's
/// range, floats as they are.
fn ply_unit(v: f64, ty: &str) -> f32 {
    let scale = match ty {
        "uchar" | "uint8" | "char" | "int8" => 255.0,
        "ushort" | "uint16" | "short" | "int16" => 65535.0,
        "float" | "float32" | "double" | "float64" => 1.0,
        _ => 255.0,
    };
    (v / scale).clamp(0.0, 1.0) as f32
}

/// [`parse_ply`] with vertex colours (`red`, `green`, `blue`, or `diffuse_…`) and texture
/// coordinates (per vertex `u`/`v`, `s`/`t`, `texture_u`/`texture_v`, or a face's
/// `texcoord` list) with the texture named by `comment TextureFile` (read through
/// `files`).
pub fn parse_ply_appearance(bytes: &[u8], files: &SideFiles) -> Result<AppearedMesh, String> {
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
    let mut texture_file: Option<String> = None;
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
            ["comment", key, ..] if key.eq_ignore_ascii_case("texturefile") => {
                let rest = line.trim_start()["comment".len()..].trim_start();
                texture_file = Some(rest[key.len()..].trim().to_string());
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
    let vertex_props = elements
        .iter()
        .find(|e| e.0 == "vertex")
        .map(|e| e.2.clone())
        .unwrap_or_default();
    let has = |names: &[&str]| names.iter().all(|n| vertex_props.iter().any(|p| p.0 == *n));
    let color_names: Option<[&str; 3]> = [
        ["red", "green", "blue"],
        ["diffuse_red", "diffuse_green", "diffuse_blue"],
        ["r", "g", "b"],
    ]
    .into_iter()
    .find(|n| has(n));
    let uv_names: Option<[&str; 2]> = [
        ["u", "v"],
        ["s", "t"],
        ["texture_u", "texture_v"],
        ["texture_s", "texture_t"],
    ]
    .into_iter()
    .find(|n| has(n));
    let mut vertex_color: Vec<[f32; 3]> = Vec::new();
    let mut vertex_uv: Vec<[f32; 2]> = Vec::new();
    // Per triangle, its corners' texture coordinates from a face's `texcoord` list.
    let mut face_uv: Vec<[[f32; 2]; 3]> = Vec::new();
    let mut any_face_uv = false;
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
            let mut rgb = [1.0f32; 3];
            let mut uv = [0.0f32; 2];
            let (mut face_polygon, mut face_tex): (Vec<u32>, Vec<f32>) = (Vec::new(), Vec::new());
            for (pname, ty, list) in props {
                match list {
                    Some(ct) => {
                        let c = next(ct, &mut pos)?;
                        if !(c.is_finite() && c >= 0.0 && c.fract() == 0.0 && c <= 1e6) {
                            return Err(format!("PLY list `{pname}` has a bad length {c}"));
                        }
                        let n = c as usize;
                        if name == "face" && (pname == "vertex_indices" || pname == "vertex_index")
                        {
                            face_polygon.clear();
                            for _ in 0..n {
                                face_polygon.push(next(ty, &mut pos)? as u32);
                            }
                        } else if name == "face" && pname == "texcoord" {
                            face_tex.clear();
                            for _ in 0..n {
                                face_tex.push(next(ty, &mut pos)? as f32);
                            }
                        } else {
                            for _ in 0..n {
                                next(ty, &mut pos)?;
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
                                p => {
                                    if let Some(k) =
                                        color_names.and_then(|c| c.iter().position(|n| *n == p))
                                    {
                                        rgb[k] = ply_unit(v, ty);
                                    }
                                    if let Some(k) =
                                        uv_names.and_then(|c| c.iter().position(|n| *n == p))
                                    {
                                        uv[k] = v as f32;
                                    }
                                }
                            }
                        }
                    }
                }
            }
            if name == "vertex" {
                mesh.positions.push(Point3::new(xyz[0], xyz[1], xyz[2]));
                if color_names.is_some() {
                    vertex_color.push(rgb);
                }
                if uv_names.is_some() {
                    vertex_uv.push([uv[0], 1.0 - uv[1]]);
                }
            }
            if name == "face" {
                let n = face_polygon.len();
                let tex_ok = face_tex.len() == 2 * n;
                any_face_uv |= tex_ok && n >= 3;
                let corner = |k: usize| {
                    if tex_ok {
                        [face_tex[2 * k], 1.0 - face_tex[2 * k + 1]]
                    } else {
                        [0.0; 2]
                    }
                };
                for k in 1..n.saturating_sub(1) {
                    mesh.triangles
                        .push([face_polygon[0], face_polygon[k], face_polygon[k + 1]]);
                    face_uv.push([corner(0), corner(k), corner(k + 1)]);
                }
            }
        }
    }
    let mut warnings = Vec::new();
    // Vertex attributes per corner; an index out of range is reported by `check`.
    let corners = |t: &[u32; 3]| t.map(|i| i as usize);
    let corner_color = (!vertex_color.is_empty()).then(|| {
        mesh.triangles
            .iter()
            .map(|t| corners(t).map(|i| vertex_color.get(i).copied().unwrap_or([1.0; 3])))
            .collect::<Vec<_>>()
    });
    let corner_uv = if any_face_uv {
        Some(face_uv)
    } else if !vertex_uv.is_empty() {
        Some(
            mesh.triangles
                .iter()
                .map(|t| corners(t).map(|i| vertex_uv.get(i).copied().unwrap_or([0.0; 2])))
                .collect::<Vec<_>>(),
        )
    } else {
        None
    };
    let texture = match (&texture_file, &corner_uv) {
        (Some(file), Some(_)) => load_texture(files, file)
            .map_err(|e| warnings.push(format!("TextureFile {e}; the mesh keeps its colour")))
            .ok()
            .map(Arc::new),
        (Some(file), None) => {
            warnings.push(format!(
                "TextureFile `{file}` is named but the PLY has no texture coordinates; the mesh keeps its colour"
            ));
            None
        }
        _ => None,
    };
    if texture.is_none() && corner_color.is_none() {
        return Ok(AppearedMesh {
            mesh,
            surface: None,
            warnings,
        });
    }
    let n = mesh.triangles.len();
    let surface = SurfaceAppearance::new(
        vec![Material {
            name: texture_file.unwrap_or_else(|| "vertex colours".into()),
            color: [1.0; 3],
            texture: texture.clone(),
        }],
        vec![0; n],
        texture.is_some().then_some(corner_uv).flatten(),
        corner_color,
    )
    .map_err(|e| e.to_string())?;
    Ok(AppearedMesh {
        mesh,
        surface: Some(Arc::new(surface)),
        warnings,
    })
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
