//! URDF models (robots, PartNet-Mobility assets) as object models: one part per link with
//! geometry, placed at the rest configuration; joints converted to the canonical-frame
//! convention (origin and axis expressed in the model frame at rest). Malformed values get
//! an error naming the element, the joint or link, and the attribute.

use crate::meshio::load_appeared_mesh;
use crate::texture::SideFiles;
use crate::{read_text, DataError, Result};
use agentstar_geom::kinematics::{JointDef, JointKind};
use agentstar_geom::pose::Rigid;
use agentstar_geom::primitives::{cuboid, cylinder, uv_sphere};
use agentstar_geom::{
    KinematicTree, Matrix3, ObjectModel, Part, SurfaceAppearance, TriMesh, UnitQuaternion, Vector3,
};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

struct UrdfJoint {
    name: String,
    kind: JointKind,
    parent: String,
    child: String,
    origin: Rigid,
    axis: Vector3,
    limit: Option<(f64, f64)>,
}

fn numbers(s: &str, n: usize, what: &str) -> std::result::Result<Vec<f64>, String> {
    let v: Vec<&str> = s.split_whitespace().collect();
    if v.len() != n {
        return Err(format!("{what} must hold {n} numbers, got \"{s}\""));
    }
    v.iter()
        .map(|t| match t.parse::<f64>() {
            Ok(x) if x.is_finite() => Ok(x),
            _ => Err(format!("{what} is not a number: \"{s}\"")),
        })
        .collect()
}

fn attr_numbers(
    node: roxmltree::Node,
    attr: &str,
    n: usize,
    owner: &str,
    default: Option<Vec<f64>>,
) -> std::result::Result<Vec<f64>, String> {
    match node.attribute(attr) {
        Some(s) => numbers(
            s,
            n,
            &format!(
                "{owner}: attribute `{attr}` of <{}>",
                node.tag_name().name()
            ),
        ),
        None => default.ok_or_else(|| {
            format!(
                "{owner}: <{}> needs attribute `{attr}`",
                node.tag_name().name()
            )
        }),
    }
}

fn origin_of(parent: roxmltree::Node, owner: &str) -> std::result::Result<Rigid, String> {
    match parent.children().find(|c| c.has_tag_name("origin")) {
        None => Ok(Rigid::identity()),
        Some(o) => {
            let xyz = attr_numbers(o, "xyz", 3, owner, Some(vec![0.0; 3]))?;
            let rpy = attr_numbers(o, "rpy", 3, owner, Some(vec![0.0; 3]))?;
            let rot = UnitQuaternion::from_euler_angles(rpy[0], rpy[1], rpy[2]);
            Ok(Rigid::from_parts(
                nalgebra::Translation3::new(xyz[0], xyz[1], xyz[2]),
                rot,
            ))
        }
    }
}

fn resolve_mesh(dir: &Path, filename: &str) -> Vec<PathBuf> {
    if let Some(rest) = filename.strip_prefix("package://") {
        // package://<pkg>/<path>: try the path under the URDF's directory and its parent.
        let after_pkg = rest.split_once('/').map(|(_, p)| p).unwrap_or(rest);
        return vec![
            dir.join(after_pkg),
            dir.join(rest),
            dir.parent().unwrap_or(dir).join(rest),
        ];
    }
    let f = filename.strip_prefix("file://").unwrap_or(filename);
    vec![dir.join(f)]
}

/// Loads a URDF file and the meshes it references (relative to the file).
pub fn load_urdf(path: &Path) -> Result<ObjectModel> {
    Ok(load_urdf_with_warnings(path)?.0)
}

/// The grey of a visual without a material.
const URDF_DEFAULT_COLOR: [f32; 3] = [0.7, 0.7, 0.72];

/// A visual's colour: its `<material>`'s `<color rgba>`, or the colour of the robot-level
/// `<material>` of the same name.
fn visual_color(
    visual: roxmltree::Node,
    named: &BTreeMap<String, [f32; 3]>,
    owner: &str,
) -> std::result::Result<Option<[f32; 3]>, String> {
    let Some(material) = visual.children().find(|c| c.has_tag_name("material")) else {
        return Ok(None);
    };
    if let Some(rgba) = material.children().find(|c| c.has_tag_name("color")) {
        let c = attr_numbers(rgba, "rgba", 4, owner, None)?;
        return Ok(Some([c[0], c[1], c[2]].map(|v| v.clamp(0.0, 1.0) as f32)));
    }
    Ok(material
        .attribute("name")
        .and_then(|n| named.get(n))
        .copied())
}

/// [`load_urdf`] with what reading the meshes' appearance gave to say (a texture that does
/// not read). Each link's colour is its visuals' materials (a `<material>` of the visual or
/// one defined at the robot level by name); a mesh with an appearance of its own (an OBJ's
/// materials, a PLY's vertex colours, a GLB's textures) keeps it.
pub fn load_urdf_with_warnings(path: &Path) -> Result<(ObjectModel, Vec<String>)> {
    let text = read_text(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    let err = |m: String| DataError::invalid(path, m);
    let doc = roxmltree::Document::parse(&text).map_err(|e| err(format!("not valid XML: {e}")))?;
    let robot = doc.root_element();
    if !robot.has_tag_name("robot") {
        return Err(err(format!(
            "the root element is <{}>, expected <robot>",
            robot.tag_name().name()
        )));
    }
    let mut warnings = Vec::new();
    let mut named_colors: BTreeMap<String, [f32; 3]> = BTreeMap::new();
    for m in robot.children().filter(|n| n.has_tag_name("material")) {
        let (Some(name), Some(rgba)) = (
            m.attribute("name"),
            m.children().find(|c| c.has_tag_name("color")),
        ) else {
            continue;
        };
        let c = attr_numbers(rgba, "rgba", 4, &format!("material `{name}`"), None).map_err(&err)?;
        named_colors.insert(
            name.to_string(),
            [c[0], c[1], c[2]].map(|v| v.clamp(0.0, 1.0) as f32),
        );
    }
    // Links with their geometry in the link frame.
    let mut links: BTreeMap<String, (TriMesh, SurfaceAppearance)> = BTreeMap::new();
    let mut link_order = Vec::new();
    for link in robot.children().filter(|n| n.has_tag_name("link")) {
        let name = link
            .attribute("name")
            .ok_or_else(|| err("a <link> has no name".into()))?
            .to_string();
        let owner = format!("link `{name}`");
        if links.contains_key(&name) {
            return Err(err(format!(
                "{owner} is defined twice (link names must be unique)"
            )));
        }
        let mut mesh = TriMesh::default();
        let mut look = SurfaceAppearance::plain(&name, URDF_DEFAULT_COLOR, 0);
        for visual in link.children().filter(|n| n.has_tag_name("visual")) {
            let origin = origin_of(visual, &owner).map_err(&err)?;
            let Some(geometry) = visual.children().find(|c| c.has_tag_name("geometry")) else {
                continue;
            };
            let Some(shape) = geometry.children().find(|c| c.is_element()) else {
                continue;
            };
            let color = visual_color(visual, &named_colors, &owner).map_err(&err)?;
            let mut own_look = None;
            let g = match shape.tag_name().name() {
                "box" => {
                    let s = attr_numbers(shape, "size", 3, &owner, None).map_err(&err)?;
                    cuboid(s[0], s[1], s[2]).map_err(|e| err(format!("{owner}: {e}")))?
                }
                "cylinder" => {
                    let r = attr_numbers(shape, "radius", 1, &owner, None).map_err(&err)?[0];
                    let l = attr_numbers(shape, "length", 1, &owner, None).map_err(&err)?[0];
                    cylinder(r, l, 48).map_err(|e| err(format!("{owner}: {e}")))?
                }
                "sphere" => {
                    let r = attr_numbers(shape, "radius", 1, &owner, None).map_err(&err)?[0];
                    uv_sphere(r, 32, 16).map_err(|e| err(format!("{owner}: {e}")))?
                }
                "mesh" => {
                    let file = shape.attribute("filename").ok_or_else(|| err(format!("{owner}: <mesh> needs attribute `filename`")))?;
                    let scale = attr_numbers(shape, "scale", 3, &owner, Some(vec![1.0; 3])).map_err(&err)?;
                    let candidates = resolve_mesh(dir, file);
                    let found = candidates.iter().find(|p| p.is_file()).ok_or_else(|| err(format!("{owner}: mesh file `{file}` not found (looked at {})", candidates.iter().map(|p| p.display().to_string()).collect::<Vec<_>>().join(", "))))?;
                    let dir = found.parent().unwrap_or(Path::new("."));
                    let m = load_appeared_mesh(found, &SideFiles::beside(dir)).map_err(|e| err(format!("{owner}: {e}")))?;
                    warnings.extend(m.warnings.iter().map(|w| format!("{owner}: {}: {w}", found.display())));
                    let mirrors = scale[0] * scale[1] * scale[2] < 0.0;
                    own_look = m.surface.map(|s| if mirrors { s.with_corners_swapped() } else { (*s).clone() });
                    m.mesh.transformed(&Matrix3::from_diagonal(&Vector3::new(scale[0], scale[1], scale[2])), &Vector3::zeros())
                }
                other => return Err(err(format!("{owner}: unsupported geometry <{other}> (box, cylinder, sphere and mesh are supported)"))),
            };
            let rot = origin.rotation.to_rotation_matrix().into_inner();
            let visual_look = own_look.unwrap_or_else(|| {
                SurfaceAppearance::plain(
                    &name,
                    color.unwrap_or(URDF_DEFAULT_COLOR),
                    g.triangles.len(),
                )
            });
            look = look
                .appended(&visual_look)
                .map_err(|e| err(format!("{owner}: {e}")))?;
            mesh.append(&g.transformed(&rot, &origin.translation.vector));
        }
        link_order.push(name.clone());
        links.insert(name, (mesh, look));
    }
    let mut joints = Vec::new();
    for j in robot.children().filter(|n| n.has_tag_name("joint")) {
        let name = j
            .attribute("name")
            .ok_or_else(|| err("a <joint> has no name".into()))?
            .to_string();
        let owner = format!("joint `{name}`");
        if joints.iter().any(|o: &UrdfJoint| o.name == name) {
            return Err(err(format!(
                "{owner} is defined twice (joint names must be unique)"
            )));
        }
        let ty = j.attribute("type").unwrap_or("");
        let kind = match ty {
            "revolute" => JointKind::Revolute,
            "continuous" => JointKind::Continuous,
            "prismatic" => JointKind::Prismatic,
            "fixed" => JointKind::Fixed,
            other => return Err(err(format!("{owner}: type \"{other}\" is not supported (revolute, continuous, prismatic, fixed)"))),
        };
        let link_of = |tag: &str| -> Result<String> {
            let n = j
                .children()
                .find(|c| c.has_tag_name(tag))
                .ok_or_else(|| err(format!("{owner}: missing <{tag}>")))?;
            let l = n
                .attribute("link")
                .ok_or_else(|| err(format!("{owner}: <{tag}> needs attribute `link`")))?;
            if !links.contains_key(l) {
                return Err(err(format!(
                    "{owner}: <{tag}> names link `{l}`, which is not defined"
                )));
            }
            Ok(l.to_string())
        };
        let (parent, child) = (link_of("parent")?, link_of("child")?);
        let origin = origin_of(j, &owner).map_err(&err)?;
        let axis = match j.children().find(|c| c.has_tag_name("axis")) {
            Some(a) => {
                attr_numbers(a, "xyz", 3, &owner, Some(vec![1.0, 0.0, 0.0])).map_err(&err)?
            }
            None => vec![1.0, 0.0, 0.0],
        };
        let axis_norm = (axis[0].powi(2) + axis[1].powi(2) + axis[2].powi(2)).sqrt();
        if kind != JointKind::Fixed && axis_norm < 1e-9 {
            return Err(err(format!(
                "{owner}: <axis xyz> is the zero vector; a moving joint needs a direction"
            )));
        }
        let limit = match (kind, j.children().find(|c| c.has_tag_name("limit"))) {
            (JointKind::Revolute | JointKind::Prismatic, Some(l)) => {
                let lo = attr_numbers(l, "lower", 1, &owner, Some(vec![0.0])).map_err(&err)?[0];
                let hi = attr_numbers(l, "upper", 1, &owner, Some(vec![0.0])).map_err(&err)?[0];
                if lo > hi {
                    return Err(err(format!(
                        "{owner}: <limit> lower {lo} is above upper {hi}"
                    )));
                }
                Some((lo, hi))
            }
            (JointKind::Revolute | JointKind::Prismatic, None) => {
                return Err(err(format!(
                    "{owner}: a {ty} joint needs <limit lower=… upper=…>"
                )))
            }
            _ => None,
        };
        joints.push(UrdfJoint {
            name,
            kind,
            parent,
            child,
            origin,
            axis: Vector3::new(axis[0], axis[1], axis[2]),
            limit,
        });
    }
    // A link is the child of at most one joint: a second one closes a kinematic loop,
    // which URDF cannot express.
    for (i, j) in joints.iter().enumerate() {
        if let Some(first) = joints[..i].iter().find(|o| o.child == j.child) {
            return Err(err(format!(
                "link `{}` is the child of two joints (`{}` and `{}`): the joints form a kinematic loop, and URDF links must form a tree",
                j.child, first.name, j.name
            )));
        }
        if j.child == j.parent {
            return Err(err(format!(
                "joint `{}`: link `{}` is its own parent",
                j.name, j.child
            )));
        }
    }
    // Rest placement of every link, from the root down.
    let children: Vec<&str> = joints.iter().map(|j| j.child.as_str()).collect();
    let roots: Vec<&String> = link_order
        .iter()
        .filter(|l| !children.contains(&l.as_str()))
        .collect();
    if roots.len() != 1 {
        return Err(err(format!(
            "the links must form one tree; found {} root links ({})",
            roots.len(),
            roots
                .iter()
                .map(|r| format!("`{r}`"))
                .collect::<Vec<_>>()
                .join(", ")
        )));
    }
    let mut world: BTreeMap<String, Rigid> = BTreeMap::new();
    world.insert(roots[0].clone(), Rigid::identity());
    let mut joint_world: BTreeMap<String, Rigid> = BTreeMap::new();
    let mut changed = true;
    while changed {
        changed = false;
        for j in &joints {
            if world.contains_key(&j.child) {
                continue;
            }
            if let Some(p) = world.get(&j.parent).copied() {
                let jw = p * j.origin;
                joint_world.insert(j.name.clone(), jw);
                world.insert(j.child.clone(), jw);
                changed = true;
            }
        }
    }
    if world.len() != link_order.len() {
        return Err(err(
            "the joints do not connect every link to the root (a cycle or a detached link)".into(),
        ));
    }
    let mut parts = Vec::new();
    for name in &link_order {
        let (Some((mesh, look)), Some(&w)) = (links.get(name), world.get(name)) else {
            continue;
        };
        if mesh.triangles.is_empty() {
            continue;
        }
        let rot = w.rotation.to_rotation_matrix().into_inner();
        let placed = mesh.clone().transformed(&rot, &w.translation.vector);
        parts.push(link_part(name, placed, look).map_err(|e| err(e.to_string()))?);
    }
    if parts.is_empty() {
        return Err(err("no link has visual geometry".into()));
    }
    let part_names: Vec<String> = parts.iter().map(|p| p.name.clone()).collect();
    let parent_joint = |link: &str| {
        joints
            .iter()
            .find(|j| j.child == link)
            .map(|j| j.name.clone())
    };
    let defs: Vec<JointDef> = joints
        .iter()
        .map(|j| {
            let jw = joint_world
                .get(&j.name)
                .copied()
                .unwrap_or_else(Rigid::identity);
            let to_interface = |v: f64| {
                if j.kind == JointKind::Revolute {
                    v.to_degrees()
                } else {
                    v
                }
            };
            JointDef {
                name: j.name.clone(),
                kind: j.kind,
                parent: parent_joint(&j.parent),
                child: if part_names.contains(&j.child) {
                    vec![j.child.clone()]
                } else {
                    vec![]
                },
                origin: jw.translation.vector,
                axis: jw.rotation * j.axis,
                limit: j.limit.map(|(lo, hi)| (to_interface(lo), to_interface(hi))),
            }
        })
        .collect();
    let tree = KinematicTree::new(defs, &part_names).map_err(|e| err(e.to_string()))?;
    Ok((ObjectModel { parts, tree }, warnings))
}

/// A link's part: one colour where its visuals share one plain material, else its
/// appearance triangle by triangle. The first (empty) material of `look` is the seed of
/// the appending, never used by a triangle.
fn link_part(name: &str, mesh: TriMesh, look: &SurfaceAppearance) -> agentstar_geom::Result<Part> {
    let used: std::collections::BTreeSet<u16> = look.triangle_material().iter().copied().collect();
    let materials = look.materials();
    let plain = look.corner_color().is_none()
        && used.iter().all(|&m| {
            let first = &materials[usize::from(*used.iter().next().unwrap_or(&m))];
            let this = &materials[usize::from(m)];
            this.texture.is_none() && this.color == first.color
        });
    if plain {
        let color = used
            .iter()
            .next()
            .map_or(URDF_DEFAULT_COLOR, |&m| materials[usize::from(m)].color);
        return Ok(Part::new(name, mesh, color));
    }
    Part::new(name, mesh, URDF_DEFAULT_COLOR).with_surface(Arc::new(look.clone()))
}
