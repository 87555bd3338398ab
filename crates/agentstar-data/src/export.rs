//! Exports of an object model: GLB (canonical rest pose, one node per part named after it,
//! glTF's Y-up: `p_gltf = (x, z, −y)` of canonical) and URDF with one OBJ mesh per part.

use crate::atomic::write_atomic;
use crate::gltf_write::GltfBuilder;
use crate::meshio::{obj_text, parse_glb};
use crate::{DataError, Result};
use agentstar_geom::kinematics::JointKind;
use agentstar_geom::ObjectModel;
use serde_json::json;
use std::path::Path;

/// The GLB bytes of the model at rest, with each part's appearance
/// ([`crate::gltf_write`]).
pub fn glb_bytes(model: &ObjectModel) -> Vec<u8> {
    let mut builder = GltfBuilder::default();
    let (mut nodes, mut meshes) = (vec![], vec![]);
    for (i, part) in model.parts.iter().enumerate() {
        meshes.push(builder.part_mesh(part, |p| [p.x as f32, p.z as f32, -p.y as f32]));
        nodes.push(json!({"name": part.name, "mesh": i}));
    }
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("agentstar ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": (0..model.parts.len()).collect::<Vec<_>>()}],
        "nodes": nodes, "meshes": meshes,
    });
    let bin = builder.finish(&mut doc);
    glb_container(&doc, bin)
}

/// The binary glTF container: header, JSON chunk, BIN chunk, each padded to four bytes.
pub(crate) fn glb_container(doc: &serde_json::Value, mut bin: Vec<u8>) -> Vec<u8> {
    let mut json_bytes = serde_json::to_vec(doc).unwrap_or_default();
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json_bytes);
    out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&bin);
    out
}

/// Writes `object.glb` atomically and checks, by reading it back, that every part is a node
/// named after it.
pub fn write_glb(model: &ObjectModel, path: &Path) -> Result<()> {
    let bytes = glb_bytes(model);
    let parts = parse_glb(&bytes).map_err(|e| {
        DataError::invalid(path, format!("the exported GLB does not read back: {e}"))
    })?;
    for p in &model.parts {
        if !parts.iter().any(|(n, _)| n == &p.name) {
            return Err(DataError::invalid(
                path,
                format!("part `{}` is missing from the exported GLB", p.name),
            ));
        }
    }
    write_atomic(path, &bytes)
}

/// Writes a model of one part as `path` (OBJ) with, where the part has an appearance beyond
/// its colour, its material library (`STEM.mtl`: `Kd`, `map_Kd`) and textures (`STEM_tJ.png`)
/// beside it, each file atomically (the images and the library before the OBJ that names
/// them). A model of several parts is refused: OBJ keeps no joints or part frames.
pub fn write_obj(model: &ObjectModel, path: &Path) -> Result<()> {
    let [part] = model.parts.as_slice() else {
        return Err(DataError::invalid(
            path,
            format!(
                "an OBJ file holds one part here; this model has {}",
                model.parts.len()
            ),
        ));
    };
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "model".into());
    let dir = path.parent().unwrap_or(Path::new("."));
    match &part.surface {
        None => write_atomic(path, obj_text(&part.mesh, &part.name).as_bytes()),
        Some(surface) => {
            let (obj, mtl, images) = obj_with_materials(&part.mesh, &part.name, &stem, surface);
            for (name, png) in images {
                write_atomic(&dir.join(name), &png)?;
            }
            write_atomic(&dir.join(format!("{stem}.mtl")), mtl.as_bytes())?;
            write_atomic(path, obj.as_bytes())
        }
    }
}

/// A part with its appearance as OBJ text (`mtllib STEM.mtl`, a `usemtl` group per
/// material, `vt` per corner with `v` up the image, and where the part has vertex colours
/// one `v x y z r g b` per corner), its material library (`Kd`, `map_Kd`) and its textures
/// as PNG files (`STEM_tJ.png`) beside it.
fn obj_with_materials(
    mesh: &agentstar_geom::TriMesh,
    name: &str,
    stem: &str,
    surface: &agentstar_geom::SurfaceAppearance,
) -> (String, String, Vec<(String, Vec<u8>)>) {
    use std::fmt::Write;
    let mut obj = format!("# agentstar\nmtllib {stem}.mtl\no {name}\n");
    let colors = surface.corner_color();
    let uvs = surface.corner_uv();
    // Vertex colours are per corner: one vertex per corner then, else the mesh's own.
    match colors {
        Some(c) => {
            for (t, tri) in mesh.triangles.iter().enumerate() {
                for k in 0..3 {
                    let p = mesh.positions[tri[k] as usize];
                    let [r, g, b] = c[t][k];
                    let _ = writeln!(obj, "v {} {} {} {r} {g} {b}", p.x, p.y, p.z);
                }
            }
        }
        None => {
            for p in &mesh.positions {
                let _ = writeln!(obj, "v {} {} {}", p.x, p.y, p.z);
            }
        }
    }
    if let Some(uv) = uvs {
        for t in uv {
            for c in t {
                let _ = writeln!(obj, "vt {} {}", c[0], 1.0 - c[1]);
            }
        }
    }
    let mut mtl = String::from("# agentstar\n");
    let mut images: Vec<(String, Vec<u8>)> = Vec::new();
    let mut written: Vec<(*const agentstar_geom::Texture, String)> = Vec::new();
    for (mi, material) in surface.materials().iter().enumerate() {
        let c = material.color;
        let _ = write!(mtl, "newmtl m{mi}\nKd {} {} {}\n", c[0], c[1], c[2]);
        if let (Some(t), Some(_)) = (&material.texture, uvs) {
            let key = std::sync::Arc::as_ptr(t);
            let file = match written.iter().find(|(k, _)| *k == key) {
                Some((_, f)) => Some(f.clone()),
                // A texture that does not encode leaves the material its colour.
                None => crate::texture::texture_png(t).ok().map(|png| {
                    let f = format!("{stem}_t{}.png", images.len());
                    images.push((f.clone(), png));
                    written.push((key, f.clone()));
                    f
                }),
            };
            if let Some(f) = file {
                let _ = writeln!(mtl, "map_Kd {f}");
            }
        }
        let _ = writeln!(obj, "usemtl m{mi}");
        for (t, tri) in mesh.triangles.iter().enumerate() {
            if usize::from(surface.triangle_material()[t]) != mi {
                continue;
            }
            let corner = |k: usize| {
                let v = if colors.is_some() {
                    3 * t + k + 1
                } else {
                    tri[k] as usize + 1
                };
                match uvs {
                    Some(_) => format!("{v}/{}", 3 * t + k + 1),
                    None => v.to_string(),
                }
            };
            let _ = writeln!(obj, "f {} {} {}", corner(0), corner(1), corner(2));
        }
    }
    (obj, mtl, images)
}

fn xml_escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes `<dir>/<robot>.urdf` and `<dir>/meshes/<part>.obj`. Each part is a link whose
/// frame sits at its joint's origin (canonical axes); parts without a joint hang from
/// `base_link` by fixed joints; further parts of a joint's group hang from its first part.
/// Revolute limits are written in radians, prismatic limits in canonical units.
pub fn write_urdf(model: &ObjectModel, dir: &Path, robot: &str) -> Result<std::path::PathBuf> {
    let joints = model.tree.joints();
    // Origin of each part's link frame: its joint's origin, or zero.
    let frame_origin = |part: usize| {
        model
            .tree
            .part_joint(part)
            .map(|j| joints[j].origin)
            .unwrap_or_default()
    };
    let file_stem = |name: &str| {
        name.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                    c
                } else {
                    '_'
                }
            })
            .collect::<String>()
    };
    let mut x = format!(
        "<?xml version=\"1.0\"?>\n<robot name=\"{}\">\n  <link name=\"base_link\"/>\n",
        xml_escape(robot)
    );
    for (i, part) in model.parts.iter().enumerate() {
        let o = frame_origin(i);
        let local = (*part.mesh).clone().translated(-o);
        let stem = file_stem(&part.name);
        let rel = format!("meshes/{stem}.obj");
        match &part.surface {
            None => write_atomic(&dir.join(&rel), obj_text(&local, &part.name).as_bytes())?,
            Some(surface) => {
                let (obj, mtl, images) = obj_with_materials(&local, &part.name, &stem, surface);
                for (name, png) in images {
                    write_atomic(&dir.join("meshes").join(name), &png)?;
                }
                write_atomic(&dir.join(format!("meshes/{stem}.mtl")), mtl.as_bytes())?;
                write_atomic(&dir.join(&rel), obj.as_bytes())?;
            }
        }
        let c = part.color;
        x.push_str(&format!(
            "  <link name=\"{n}\">\n    <visual>\n      <geometry><mesh filename=\"{rel}\"/></geometry>\n      <material name=\"{n}_color\"><color rgba=\"{} {} {} 1\"/></material>\n    </visual>\n    <collision><geometry><mesh filename=\"{rel}\"/></geometry></collision>\n  </link>\n",
            c[0], c[1], c[2], n = xml_escape(&part.name)
        ));
    }
    // The link that carries each joint's motion: the first part of its child group.
    let child_link = |j: usize| model.part_index(&joints[j].child[0]).unwrap_or(0);
    for (i, part) in model.parts.iter().enumerate() {
        let n = xml_escape(&part.name);
        match model.tree.part_joint(i) {
            None => x.push_str(&format!(
                "  <joint name=\"{n}_fixed\" type=\"fixed\">\n    <parent link=\"base_link\"/>\n    <child link=\"{n}\"/>\n    <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n  </joint>\n"
            )),
            Some(j) if child_link(j) != i => {
                let lead = child_link(j);
                x.push_str(&format!(
                    "  <joint name=\"{n}_fixed\" type=\"fixed\">\n    <parent link=\"{}\"/>\n    <child link=\"{n}\"/>\n    <origin xyz=\"0 0 0\" rpy=\"0 0 0\"/>\n  </joint>\n",
                    xml_escape(&model.parts[lead].name)
                ));
            }
            Some(j) => {
                let jd = &joints[j];
                let (parent_link, parent_origin) = match jd.parent.as_deref().and_then(|p| model.tree.joint_index(p)) {
                    Some(pj) => (model.parts[child_link(pj)].name.clone(), joints[pj].origin),
                    None => ("base_link".to_string(), Default::default()),
                };
                let o = jd.origin - parent_origin;
                let a = jd.axis.normalize();
                let ty = match jd.kind {
                    JointKind::Revolute => "revolute",
                    JointKind::Continuous => "continuous",
                    JointKind::Prismatic => "prismatic",
                    JointKind::Fixed => "fixed",
                };
                let limit = match jd.limit {
                    Some((lo, hi)) => format!("    <limit lower=\"{}\" upper=\"{}\" effort=\"1\" velocity=\"1\"/>\n", jd.to_internal(lo), jd.to_internal(hi)),
                    None => String::new(),
                };
                x.push_str(&format!(
                    "  <joint name=\"{}\" type=\"{ty}\">\n    <parent link=\"{}\"/>\n    <child link=\"{n}\"/>\n    <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n    <axis xyz=\"{} {} {}\"/>\n{limit}  </joint>\n",
                    xml_escape(&jd.name),
                    xml_escape(&parent_link),
                    o.x, o.y, o.z, a.x, a.y, a.z
                ));
            }
        }
    }
    x.push_str("</robot>\n");
    let path = dir.join(format!("{}.urdf", file_stem(robot)));
    write_atomic(&path, x.as_bytes())?;
    Ok(path)
}
