//! The tracked motion as a glTF animation (GLB), and reading it back.
//!
//! Layout: one root node `object` whose translation, rotation and scale are animated with
//! `gltf_from_world · world_from_object` per keyframe (the similarity with the run's scale;
//! `gltf_from_world` turns OpenCV axes, +Y down and +Z forward, into glTF's +Y up and −Z
//! forward, a half turn about X); under it one node per part, named after the part, whose
//! mesh is in canonical coordinates and whose translation and rotation are animated with the
//! part's forward kinematics. Times are the keyframes' `time_s`. Linear interpolation (glTF
//! slerps rotations). The animation's `extras` carry the frame names, the joint states in
//! interface units (degrees or canonical units) and the joint definitions, so a reader gets
//! exact joint states back; the node transforms alone already play in Blender and three.js.

use crate::gltf_write::GltfBuilder;
use crate::{DataError, Result};
use agentstar_geom::pose::{Rigid, Similarity};
use agentstar_geom::{ObjectModel, UnitQuaternion, Vector3};
use serde_json::json;
use std::collections::BTreeMap;

/// One keyframe of the animation.
#[derive(Debug, Clone)]
pub struct AnimFrame {
    pub name: String,
    pub time_s: f64,
    /// `world_from_object` with the scale (`p_world = s·R·p + t`), OpenCV world axes.
    pub world_from_object: Similarity,
    /// Joint states, internal units.
    pub states: Vec<f64>,
}

/// `gltf_from_world`: a half turn about X.
fn gltf_from_world() -> UnitQuaternion {
    UnitQuaternion::from_axis_angle(&Vector3::x_axis(), std::f64::consts::PI)
}

fn quat_xyzw(q: &UnitQuaternion) -> [f32; 4] {
    [q.i as f32, q.j as f32, q.k as f32, q.w as f32]
}

/// The animated GLB of `model` moving through `frames`. Fails when the frames are empty,
/// times do not increase, or a pose is not finite.
pub fn animated_glb_bytes(
    model: &ObjectModel,
    frames: &[AnimFrame],
) -> std::result::Result<Vec<u8>, String> {
    if frames.is_empty() {
        return Err("no keyframes to animate".into());
    }
    for w in frames.windows(2) {
        if w[1].time_s.partial_cmp(&w[0].time_s) != Some(std::cmp::Ordering::Greater) {
            return Err(format!(
                "keyframe times must increase: {} at {} s, then {} at {} s",
                w[0].name, w[0].time_s, w[1].name, w[1].time_s
            ));
        }
    }
    for f in frames {
        let s = &f.world_from_object;
        if !(s.scale.is_finite() && s.scale > 0.0 && s.translation.iter().all(|v| v.is_finite()))
            || f.states.iter().any(|v| !v.is_finite())
        {
            return Err(format!("keyframe {}: the pose is not finite", f.name));
        }
    }
    let mut bin = GltfBuilder::default();
    let (mut nodes, mut meshes) = (vec![], vec![]);
    let times: Vec<f32> = frames.iter().map(|f| f.time_s as f32).collect();
    let input = bin.floats(&times, 1, "SCALAR", true, None);
    let mut samplers = vec![];
    let mut channels = vec![];
    let mut channel =
        |node: usize, path: &str, output: usize, samplers: &mut Vec<serde_json::Value>| {
            samplers.push(json!({"input": input, "output": output, "interpolation": "LINEAR"}));
            channels.push(
                json!({"sampler": samplers.len() - 1, "target": {"node": node, "path": path}}),
            );
        };
    // Root: the object in the glTF world.
    let g = gltf_from_world();
    let (mut t, mut r, mut sc) = (vec![], vec![], vec![]);
    for f in frames {
        let w = &f.world_from_object;
        let tr = g * w.translation;
        t.extend([tr.x as f32, tr.y as f32, tr.z as f32]);
        r.extend(quat_xyzw(&(g * w.rotation)));
        sc.extend([w.scale as f32; 3]);
    }
    let first = &frames[0].world_from_object;
    let first_t = g * first.translation;
    let first_r = quat_xyzw(&(g * first.rotation));
    nodes.push(json!({"name": "object",
        "translation": [first_t.x, first_t.y, first_t.z], "rotation": first_r,
        "scale": [first.scale, first.scale, first.scale],
        "children": (1..=model.parts.len()).collect::<Vec<_>>()}));
    let out = bin.floats(&t, 3, "VEC3", false, None);
    channel(0, "translation", out, &mut samplers);
    let out = bin.floats(&r, 4, "VEC4", false, None);
    channel(0, "rotation", out, &mut samplers);
    let out = bin.floats(&sc, 3, "VEC3", false, None);
    channel(0, "scale", out, &mut samplers);
    // Parts: meshes in canonical coordinates, forward kinematics animated.
    let fk: Vec<Vec<Rigid>> = frames
        .iter()
        .map(|f| model.tree.part_transforms(&f.states))
        .collect();
    for (i, part) in model.parts.iter().enumerate() {
        meshes.push(bin.part_mesh(part, |p| [p.x as f32, p.y as f32, p.z as f32]));
        let node = i + 1;
        let a0 = &fk[0][i];
        let t0 = a0.translation.vector;
        nodes.push(json!({"name": part.name, "mesh": i,
            "translation": [t0.x, t0.y, t0.z], "rotation": quat_xyzw(&a0.rotation)}));
        if model.tree.part_joint(i).is_some() {
            let t: Vec<f32> = fk
                .iter()
                .flat_map(|a| {
                    let v = a[i].translation.vector;
                    [v.x as f32, v.y as f32, v.z as f32]
                })
                .collect();
            let r: Vec<f32> = fk.iter().flat_map(|a| quat_xyzw(&a[i].rotation)).collect();
            let out = bin.floats(&t, 3, "VEC3", false, None);
            channel(node, "translation", out, &mut samplers);
            let out = bin.floats(&r, 4, "VEC4", false, None);
            channel(node, "rotation", out, &mut samplers);
        }
    }
    let joints: BTreeMap<String, Vec<f64>> = model
        .tree
        .joints()
        .iter()
        .enumerate()
        .map(|(j, jd)| {
            (
                jd.name.clone(),
                frames
                    .iter()
                    .map(|f| jd.to_interface(f.states[j]))
                    .collect(),
            )
        })
        .collect();
    let joint_defs: Vec<_> = model
        .tree
        .joints()
        .iter()
        .map(crate::posefile::joint_json)
        .collect();
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("agentstar ", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"name": "tracked", "nodes": [0]}],
        "nodes": nodes, "meshes": meshes,
        "animations": [{"name": "tracked", "samplers": samplers, "channels": channels,
            "extras": {"agentstar": {
                "frames": frames.iter().map(|f| &f.name).collect::<Vec<_>>(),
                "times_s": frames.iter().map(|f| f.time_s).collect::<Vec<_>>(),
                "joint_states": joints, "joint_defs": joint_defs,
                "convention": "root = half turn about X · world_from_object (OpenCV world); parts in canonical coordinates (+Z up), forward kinematics per part; joint states in degrees (revolute) or canonical units (prismatic)"}}}],
    });
    let bytes = bin.finish(&mut doc);
    Ok(crate::export::glb_container(&doc, bytes))
}

/// What reading an animated GLB back gives.
#[derive(Debug, Clone)]
pub struct AnimationRead {
    pub frames: Vec<String>,
    pub times_s: Vec<f64>,
    /// Per keyframe, `world_from_object` (OpenCV world) from the root node's channels.
    pub world_from_object: Vec<Similarity>,
    /// Per part name, per keyframe, `object_from_part` from the part's channels (rest
    /// transform when the part is not animated).
    pub parts: BTreeMap<String, Vec<Rigid>>,
    /// Joint states per joint name, interface units, from the extras.
    pub joint_states: BTreeMap<String, Vec<f64>>,
}

/// Reads an animated GLB written by [`animated_glb_bytes`] (validated by the `gltf` crate on
/// the way) and samples its channels at the keyframe times.
pub fn read_animated_glb(bytes: &[u8], what: &std::path::Path) -> Result<AnimationRead> {
    let bad = |m: String| DataError::invalid(what, m);
    let gltf = gltf::Gltf::from_slice(bytes).map_err(|e| bad(format!("not a valid GLB: {e}")))?;
    let blob = gltf.blob.as_deref();
    let anim = gltf
        .animations()
        .next()
        .ok_or_else(|| bad("the GLB has no animation".into()))?;
    let extras: serde_json::Value = anim
        .extras()
        .as_ref()
        .and_then(|r| serde_json::from_str(r.get()).ok())
        .ok_or_else(|| bad("the animation has no agentstar extras".into()))?;
    let ex = &extras["agentstar"];
    let frames: Vec<String> = serde_json::from_value(ex["frames"].clone())
        .map_err(|e| bad(format!("extras.frames: {e}")))?;
    let times_s: Vec<f64> = serde_json::from_value(ex["times_s"].clone())
        .map_err(|e| bad(format!("extras.times_s: {e}")))?;
    let joint_states: BTreeMap<String, Vec<f64>> =
        serde_json::from_value(ex["joint_states"].clone())
            .map_err(|e| bad(format!("extras.joint_states: {e}")))?;
    let n = frames.len();
    // Channel outputs by (node index, path).
    let mut outputs: BTreeMap<(usize, String), Vec<Vec<f32>>> = BTreeMap::new();
    for ch in anim.channels() {
        let reader = ch.reader(|_| blob);
        let node = ch.target().node().index();
        use gltf::animation::util::ReadOutputs;
        let (path, rows): (&str, Vec<Vec<f32>>) = match reader.read_outputs() {
            Some(ReadOutputs::Translations(it)) => {
                ("translation", it.map(|v| v.to_vec()).collect())
            }
            Some(ReadOutputs::Rotations(it)) => {
                ("rotation", it.into_f32().map(|v| v.to_vec()).collect())
            }
            Some(ReadOutputs::Scales(it)) => ("scale", it.map(|v| v.to_vec()).collect()),
            _ => continue,
        };
        if rows.len() != n {
            return Err(bad(format!(
                "channel {path} of node {node} has {} keys for {n} frames",
                rows.len()
            )));
        }
        outputs.insert((node, path.to_string()), rows);
    }
    let get = |node: usize, path: &str| outputs.get(&(node, path.to_string()));
    let g_inv = gltf_from_world().inverse();
    let quat = |q: &[f32]| {
        UnitQuaternion::from_quaternion(agentstar_geom::nalgebra::Quaternion::new(
            q[3] as f64,
            q[0] as f64,
            q[1] as f64,
            q[2] as f64,
        ))
    };
    let vec3 = |v: &[f32]| Vector3::new(v[0] as f64, v[1] as f64, v[2] as f64);
    let (rt, rr, rs) = (
        get(0, "translation").ok_or_else(|| bad("the root has no translation channel".into()))?,
        get(0, "rotation").ok_or_else(|| bad("the root has no rotation channel".into()))?,
        get(0, "scale").ok_or_else(|| bad("the root has no scale channel".into()))?,
    );
    let world_from_object = (0..n)
        .map(|k| Similarity {
            scale: rs[k][0] as f64,
            rotation: g_inv * quat(&rr[k]),
            translation: g_inv * vec3(&rt[k]),
        })
        .collect();
    let mut parts = BTreeMap::new();
    for node in gltf.nodes().skip(1) {
        let name = node.name().unwrap_or("").to_string();
        let (t0, r0, _) = node.transform().decomposed();
        let rows: Vec<Rigid> = (0..n)
            .map(|k| {
                let t = get(node.index(), "translation").map_or(vec3(&t0), |v| vec3(&v[k]));
                let r = get(node.index(), "rotation").map_or(quat(&r0), |v| quat(&v[k]));
                Rigid::from_parts(agentstar_geom::nalgebra::Translation3::from(t), r)
            })
            .collect();
        parts.insert(name, rows);
    }
    Ok(AnimationRead {
        frames,
        times_s,
        world_from_object,
        parts,
        joint_states,
    })
}
