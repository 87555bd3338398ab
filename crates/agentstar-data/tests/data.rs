//! File formats end to end: a capture written by the test is read back; every kind of bad
//! input gets its own message naming the file; pose files, URDF and exports round-trip.

mod common;

use agentstar_data::capture::{CamerasJson, Capture, Keyframe, Manifest};
use agentstar_data::export::{glb_bytes, write_glb, write_urdf};
use agentstar_data::meshio::parse_glb;
use agentstar_data::posefile::PoseFile;
use agentstar_data::scenefile::{load_model, load_scene_script, ScriptDirMeshes};
use agentstar_data::urdf::load_urdf;
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{Point3, UnitQuaternion, Vector3};
use agentstar_scene::MeshSource;
use common::problems;
use image::{GrayImage, Luma, RgbImage};
use std::path::Path;

const W: u32 = 40;
const H: u32 = 30;

fn write_capture(dir: &Path, frames: usize, c2w: Vec<[[f64; 4]; 4]>) {
    let names: Vec<String> = (0..frames).map(|k| format!("{:06}.jpg", k * 10)).collect();
    std::fs::create_dir_all(dir.join("frames")).expect("dir");
    std::fs::create_dir_all(dir.join("mask_object")).expect("dir");
    std::fs::create_dir_all(dir.join("mask_hand")).expect("dir");
    for (k, n) in names.iter().enumerate() {
        RgbImage::from_pixel(W, H, image::Rgb([90, 90, 90]))
            .save(dir.join("frames").join(n))
            .expect("frame");
        let stem = &n[..6];
        GrayImage::from_fn(W, H, |x, _| Luma([if x < 20 { 255 } else { 0 }]))
            .save(dir.join("mask_object").join(format!("{stem}.png")))
            .expect("mask");
        if k == 0 {
            GrayImage::from_fn(W, H, |x, _| Luma([if x > 30 { 255 } else { 0 }]))
                .save(dir.join("mask_hand").join(format!("{stem}.png")))
                .expect("hand");
        }
    }
    let k = [[50.0, 0.0, 20.0], [0.0, 50.0, 15.0], [0.0, 0.0, 1.0]];
    let cams = CamerasJson {
        intrinsics: vec![k; c2w.len()],
        c2w,
        size: Some([W, H]),
    };
    std::fs::create_dir_all(dir.join("tracking")).expect("dir");
    std::fs::write(
        dir.join("tracking/cameras.json"),
        serde_json::to_string(&cams).expect("json"),
    )
    .expect("write");
    let kf: Vec<Keyframe> = names
        .iter()
        .enumerate()
        .map(|(i, n)| Keyframe {
            view: i,
            frame_index: Some(10 * i as i64),
            frame_name: n.clone(),
            time_s: None,
        })
        .collect();
    std::fs::write(
        dir.join("tracking/keyframes.json"),
        serde_json::to_string(&kf).expect("json"),
    )
    .expect("write");
    let m = Manifest {
        format: "capture/v1".into(),
        image_size: [W, H],
        frames: names.iter().rev().cloned().collect(), // listed out of order on purpose
        ref_frame: None,
        depth: "none".into(),
        depth_scale: None,
        dataset: None,
        source: None,
        downscale: None,
        undistorted: None,
        keyframes: None,
    };
    std::fs::write(
        dir.join("capture.json"),
        serde_json::to_string(&m).expect("json"),
    )
    .expect("write");
}

fn identity() -> [[f64; 4]; 4] {
    [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, 1.0, 0.0, 0.0],
        [0.0, 0.0, 1.0, 0.0],
        [0.0, 0.0, 0.0, 1.0],
    ]
}

fn translated(x: f64) -> [[f64; 4]; 4] {
    let mut m = identity();
    m[0][3] = x;
    m
}

#[test]
fn capture_written_by_the_test_reads_back() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(
        dir.path(),
        3,
        vec![identity(), translated(0.1), translated(0.2)],
    );
    assert!(
        Capture::validate(dir.path()).is_empty(),
        "{:?}",
        Capture::validate(dir.path())
    );
    let c = Capture::open(dir.path()).expect("open");
    // Temporal order is the integer stem, whatever the manifest's order; the reference
    // defaults to the first listed frame.
    let names: Vec<&str> = c.frames.iter().map(|f| f.name.as_str()).collect();
    assert_eq!(names, ["000000.jpg", "000010.jpg", "000020.jpg"]);
    assert_eq!(c.frames[c.ref_index].name, "000020.jpg");
    assert_eq!(c.frames[1].camera.fx, 50.0);
    assert!((c.frames[2].world_from_camera.translation.vector.x - 0.2).abs() < 1e-12);
    assert_eq!(c.load_mask(0).expect("mask").count(), 20 * 30);
    assert!(c.load_hand(0).expect("hand").is_some());
    assert!(c.load_hand(1).expect("hand").is_none());
    assert_eq!(c.frame_index("000010"), Some(1));
}

#[test]
fn missing_mask_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    std::fs::remove_file(dir.path().join("mask_object/000010.png")).expect("rm");
    let p = problems(dir.path());
    assert!(
        p.contains("mask_object/000010.png") && p.contains("missing object mask"),
        "{p}"
    );
}

#[test]
fn mask_size_mismatch_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    GrayImage::new(10, 10)
        .save(dir.path().join("mask_object/000000.png"))
        .expect("mask");
    let p = problems(dir.path());
    assert!(
        p.contains("000000.png: size 10×10 differs from image_size 40×30"),
        "{p}"
    );
}

#[test]
fn non_orthonormal_rotation_and_nan_intrinsics_are_both_reported() {
    let dir = tempfile::tempdir().expect("tmp");
    let mut bad = identity();
    bad[0][0] = 2.0;
    write_capture(dir.path(), 2, vec![identity(), bad]);
    let mut cams: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(dir.path().join("tracking/cameras.json")).expect("r"),
    )
    .expect("json");
    cams["intrinsics"][0][0][0] = serde_json::json!(-1.0);
    std::fs::write(dir.path().join("tracking/cameras.json"), cams.to_string()).expect("w");
    let p = problems(dir.path());
    assert!(p.contains("c2w[1]") && p.contains("not orthonormal"), "{p}");
    assert!(
        p.contains("intrinsics[0]") && p.contains("positive focal"),
        "{p}"
    );
}

#[test]
fn unknown_format_and_bad_stems_are_reported_together() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("capture.json")).expect("r"))
            .expect("json");
    m["format"] = serde_json::json!("capture/v9");
    m["frames"]
        .as_array_mut()
        .expect("array")
        .push(serde_json::json!("frame_a.jpg"));
    std::fs::write(dir.path().join("capture.json"), m.to_string()).expect("w");
    let p = problems(dir.path());
    assert!(p.contains("unknown format \"capture/v9\""), "{p}");
    assert!(
        p.contains("frame `frame_a.jpg`: the file stem must be a zero-padded integer"),
        "{p}"
    );
}

#[test]
fn missing_manifest_cameras_and_corrupt_files() {
    let dir = tempfile::tempdir().expect("tmp");
    assert!(problems(&dir.path().join("nope")).contains("does not exist"));
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    std::fs::remove_file(dir.path().join("tracking/cameras.json")).expect("rm");
    assert!(problems(dir.path()).contains("no cameras"));
    std::fs::write(dir.path().join("tracking/cameras.npz"), b"garbage").expect("w");
    assert!(
        problems(dir.path()).contains("cameras.npz: not a readable .npz archive"),
        "{}",
        problems(dir.path())
    );
    std::fs::write(dir.path().join("capture.json"), "{ not json").expect("w");
    assert!(problems(dir.path()).contains("capture.json: invalid manifest"));
}

#[test]
fn keyframe_view_out_of_range() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    let kf =
        r#"[{"view": 0, "frame_name": "000000.jpg"}, {"view": 7, "frame_name": "000010.jpg"}]"#;
    std::fs::write(dir.path().join("tracking/keyframes.json"), kf).expect("w");
    let p = problems(dir.path());
    assert!(p.contains("view 7 is out of range"), "{p}");
}

const LID_SCENE: &str = r#"
part("base", box(1, 0.6, 0.2));
part("lid", box(1, 0.6, 0.05).translate(0, 0, 0.125));
joint(#{ name: "hinge", type: "revolute", child: "lid", origin: [0, 0.3, 0.1], axis: [1, 0, 0], limit: [0, 120] });
"#;

/// A capture in `dir` with one frame per camera, and the lid model of [`LID_SCENE`].
fn lid_capture(dir: &Path, cameras: Vec<[[f64; 4]; 4]>) -> (Capture, agentstar_geom::ObjectModel) {
    write_capture(dir, cameras.len(), cameras);
    let cap = Capture::open(dir).expect("open");
    std::fs::write(dir.join("scene.rhai"), LID_SCENE).expect("w");
    let model = load_model(&dir.join("scene.rhai")).expect("model").model;
    (cap, model)
}

#[test]
fn pose_file_resolution_seeds_through_cameras_and_checks_joints() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model) = lid_capture(
        dir.path(),
        vec![identity(), translated(0.1), translated(0.2)],
    );
    let pose = ObjectPose::new(
        UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 0.4),
        Vector3::new(0.0, 0.0, 2.0),
    );
    let mut pf = PoseFile::initial(&cap, &model.tree, 0.2, &pose);
    pf.frames
        .get_mut("000020.jpg")
        .expect("ref")
        .joints
        .insert("hinge".into(), 30.0);
    let p = dir.path().join("pose.json");
    pf.write(&p).expect("write");
    let back = PoseFile::read(&p).expect("read");
    assert_eq!(back, pf);
    let resolved = back.resolve(&cap, &model.tree).expect("resolve");
    // Frame 000000's camera sits 0.2 left of the reference camera: the object appears 0.2
    // further right, with the reference's joint state.
    assert!(resolved[0].seeded && !resolved[2].seeded);
    assert!((resolved[0].generalised.pose.translation - Vector3::new(0.2, 0.0, 2.0)).norm() < 1e-9);
    assert!((resolved[0].generalised.states[0] - 30f64.to_radians()).abs() < 1e-12);
    // A state outside the limit names the frame and the joint.
    pf.frames
        .get_mut("000020.jpg")
        .expect("ref")
        .joints
        .insert("hinge".into(), 150.0);
    let e = pf.resolve(&cap, &model.tree).expect_err("limit");
    assert!(
        e.contains("000020.jpg") && e.contains("hinge") && e.contains("outside"),
        "{e}"
    );
}

#[test]
fn a_pose_file_states_its_quaternion_order_and_means_it() {
    let dir = tempfile::tempdir().expect("tmp");
    let (cap, model) = lid_capture(dir.path(), vec![identity(), translated(0.1)]);
    let pose = ObjectPose::new(
        UnitQuaternion::from_axis_angle(
            &agentstar_geom::nalgebra::Unit::new_normalize(Vector3::new(0.3, -0.5, 0.8)),
            1.1,
        ),
        Vector3::new(0.05, -0.02, 0.7),
    );
    let scale = 0.25;
    let p = dir.path().join("pose.json");
    PoseFile::initial(&cap, &model.tree, scale, &pose)
        .write(&p)
        .expect("write");
    // The file says how to read it...
    let raw: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&p).expect("read")).expect("json");
    let said = raw["pose_convention"]
        .as_str()
        .expect("a stated convention");
    assert!(
        said.contains("[w, x, y, z]") && said.contains("scalar first"),
        "{said}"
    );
    // ... and a reader that follows it word for word puts a canonical point where we do.
    let object_pose = &raw["frames"][raw["reference_frame"].as_str().expect("ref")]["object_pose"];
    let q: Vec<f64> = (0..4)
        .map(|k| object_pose["quaternion"][k].as_f64().expect("q"))
        .collect();
    let t: Vec<f64> = (0..3)
        .map(|k| object_pose["translation"][k].as_f64().expect("t"))
        .collect();
    let (w, x, y, z) = (q[0], q[1], q[2], q[3]);
    let rotated = |v: [f64; 3]| -> [f64; 3] {
        // R(q) v for a unit quaternion w + xi + yj + zk.
        let r = [
            [
                1.0 - 2.0 * (y * y + z * z),
                2.0 * (x * y - w * z),
                2.0 * (x * z + w * y),
            ],
            [
                2.0 * (x * y + w * z),
                1.0 - 2.0 * (x * x + z * z),
                2.0 * (y * z - w * x),
            ],
            [
                2.0 * (x * z - w * y),
                2.0 * (y * z + w * x),
                1.0 - 2.0 * (x * x + y * y),
            ],
        ];
        [0, 1, 2].map(|i| r[i][0] * v[0] + r[i][1] * v[1] + r[i][2] * v[2])
    };
    let canonical = [0.4, -0.2, 0.1];
    let by_hand = rotated(canonical.map(|c| c * scale));
    let ours = pose.with_scale(scale).transform_point(&Point3::new(
        canonical[0],
        canonical[1],
        canonical[2],
    ));
    for i in 0..3 {
        assert!((by_hand[i] + t[i] - ours[i]).abs() < 1e-6, "axis {i}");
    }
    // A file of the reference harness's, without the field, reads under the same convention.
    let mut old = raw.clone();
    old.as_object_mut()
        .expect("object")
        .remove("pose_convention");
    std::fs::write(&p, old.to_string()).expect("w");
    let back = PoseFile::read(&p).expect("read");
    assert_eq!(back.pose_convention, said);
}

#[test]
fn malformed_pose_files_are_explained() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("pose.json");
    std::fs::write(&p, r#"{"scale": 1, "reference_frame": "a", "frames": {"a": {"object_pose": {"quaternion": [1,0,0,0], "translation": [0,0,1], "joints": {"h": 1}}}}}"#).expect("w");
    let e = PoseFile::read(&p).expect_err("nested joints").to_string();
    assert!(e.contains("pose.json") && e.contains("sibling"), "{e}");
    std::fs::write(&p, r#"{"scale": -1, "reference_frame": "a", "frames": {}}"#).expect("w");
    assert!(PoseFile::read(&p)
        .expect_err("scale")
        .to_string()
        .contains("scale -1"));
    std::fs::write(&p, r#"{"scale": 1, "reference_frame": "a", "frames": {"a": {"object_pose": {"quaternion": [0,0,0,0], "translation": [0,0,1]}}}}"#).expect("w");
    assert!(PoseFile::read(&p)
        .expect_err("zero quaternion")
        .to_string()
        .contains("zero length"));
}

const URDF: &str = r#"<?xml version="1.0"?>
<robot name="cabinet">
  <link name="body"><visual><geometry><box size="0.6 0.4 0.8"/></geometry></visual></link>
  <link name="door"><visual><origin xyz="0.15 0 0"/><geometry><box size="0.3 0.02 0.7"/></geometry>
    <material name="wood"><color rgba="0.6 0.4 0.2 1"/></material></visual></link>
  <link name="knob"><visual><geometry><mesh filename="meshes/knob.obj" scale="1 1 1"/></geometry></visual></link>
  <joint name="door_hinge" type="revolute">
    <parent link="body"/><child link="door"/>
    <origin xyz="-0.3 -0.21 0" rpy="0 0 0"/><axis xyz="0 0 1"/>
    <limit lower="-1.57" upper="0" effort="1" velocity="1"/>
  </joint>
  <joint name="knob_spin" type="continuous">
    <parent link="door"/><child link="knob"/>
    <origin xyz="0.25 -0.02 0" rpy="1.5707963267948966 0 0"/><axis xyz="0 0 1"/>
  </joint>
</robot>
"#;

fn write_urdf_fixture(dir: &Path, urdf: &str) -> std::path::PathBuf {
    std::fs::create_dir_all(dir.join("meshes")).expect("dir");
    let knob = agentstar_geom::primitives::cylinder(0.02, 0.03, 16).expect("knob");
    std::fs::write(
        dir.join("meshes/knob.obj"),
        agentstar_data::meshio::obj_text(&knob, "knob"),
    )
    .expect("w");
    let p = dir.join("cabinet.urdf");
    std::fs::write(&p, urdf).expect("w");
    p
}

#[test]
fn urdf_loads_with_rest_placement_and_chain() {
    let dir = tempfile::tempdir().expect("tmp");
    let model = load_urdf(&write_urdf_fixture(dir.path(), URDF)).expect("urdf");
    assert_eq!(model.part_names(), ["body", "door", "knob"]);
    let j = &model.tree.joints()[0];
    assert_eq!(j.limit, Some((-1.57f64.to_degrees(), 0.0)));
    // Opening the door by −90° about +Z at (−0.3, −0.21): its free edge (0, −0.21) swings
    // out to (−0.3, −0.51).
    let t = model
        .tree
        .part_transforms(&[-std::f64::consts::FRAC_PI_2, 0.0]);
    let p = t[1] * Point3::new(0.0, -0.21, 0.0);
    assert!((p - Point3::new(-0.3, -0.51, 0.0)).norm() < 1e-9, "{p}");
    // The knob rides on the door (its joint's parent is the hinge).
    assert_eq!(model.tree.joints()[1].parent.as_deref(), Some("door_hinge"));
    assert!((model.parts[1].color[0] - 0.6).abs() < 1e-6);
}

#[test]
fn malformed_urdf_values_name_joint_and_attribute() {
    let dir = tempfile::tempdir().expect("tmp");
    let bad = URDF.replace("upper=\"0\"", "upper=\"-z0.008\"");
    let e = load_urdf(&write_urdf_fixture(dir.path(), &bad))
        .expect_err("malformed")
        .to_string();
    assert!(
        e.contains("joint `door_hinge`")
            && e.contains("attribute `upper` of <limit>")
            && e.contains("-z0.008"),
        "{e}"
    );
    let missing = URDF.replace("meshes/knob.obj", "meshes/gone.obj");
    let e = load_urdf(&write_urdf_fixture(dir.path(), &missing))
        .expect_err("mesh")
        .to_string();
    assert!(e.contains("link `knob`") && e.contains("gone.obj"), "{e}");
}

#[test]
fn glb_export_names_every_part_and_reads_back() {
    let dir = tempfile::tempdir().expect("tmp");
    std::fs::write(dir.path().join("scene.rhai"), LID_SCENE).expect("w");
    let model = load_model(&dir.path().join("scene.rhai"))
        .expect("model")
        .model;
    let parts = parse_glb(&glb_bytes(&model)).expect("glb");
    assert_eq!(
        parts.iter().map(|(n, _)| n.as_str()).collect::<Vec<_>>(),
        ["base", "lid"]
    );
    // Y-up in the file, Z-up again after reading: the lid still sits above the base.
    assert!((parts[1].1.bounds().min.z - 0.1).abs() < 1e-6);
    assert!((parts[0].1.volume() - 0.12).abs() < 1e-6);
    write_glb(&model, &dir.path().join("object.glb")).expect("write");
    let reloaded = load_model(&dir.path().join("object.glb"))
        .expect("reload")
        .model;
    assert_eq!(reloaded.part_names(), ["base", "lid"]);
}

#[test]
fn urdf_export_round_trips_forward_kinematics() {
    let dir = tempfile::tempdir().expect("tmp");
    let model = load_urdf(&write_urdf_fixture(dir.path(), URDF)).expect("urdf");
    let out = dir.path().join("export");
    let path = write_urdf(&model, &out, "cabinet").expect("export");
    let back = load_urdf(&path).expect("reimport");
    let states = [-0.7, 1.1];
    // The export adds fixed joints, so the re-imported joints are matched by name.
    let back_states: Vec<f64> = back
        .tree
        .joints()
        .iter()
        .map(|j| model.tree.joint_index(&j.name).map_or(0.0, |k| states[k]))
        .collect();
    let (ta, tb) = (
        model.tree.part_transforms(&states),
        back.tree.part_transforms(&back_states),
    );
    for (i, name) in model.part_names().iter().enumerate() {
        let j = back.part_index(name).expect("part");
        let a = agentstar_geom::model::transform_rigid(&model.parts[i].mesh, &ta[i]).bounds();
        let b = agentstar_geom::model::transform_rigid(&back.parts[j].mesh, &tb[j]).bounds();
        assert!(
            (a.min - b.min).norm() < 1e-5 && (a.max - b.max).norm() < 1e-5,
            "{name}: {a:?} vs {b:?}"
        );
    }
}

#[test]
fn scripts_reach_only_meshes_beside_them_and_keep_the_last_good_model() {
    let dir = tempfile::tempdir().expect("tmp");
    let src = ScriptDirMeshes::new(dir.path());
    assert!(src
        .load("../x.obj")
        .expect_err("parent")
        .contains("relative path inside"));
    assert!(src.load("/etc/passwd").is_err());
    assert!(src
        .load("notes.txt")
        .expect_err("ext")
        .contains("not a mesh file"));
    let script = dir.path().join("scene.rhai");
    std::fs::write(&script, LID_SCENE).expect("w");
    load_scene_script(&script, &Default::default()).expect("good");
    std::fs::write(&script, "part(\"a\", cilinder(1, 1));").expect("w");
    let e = load_scene_script(&script, &Default::default())
        .expect_err("bad")
        .to_string();
    assert!(
        e.contains("did you mean `cylinder`") && e.contains("last good model"),
        "{e}"
    );
    let last = agentstar_data::scenefile::last_good_script(&script).expect("kept");
    assert_eq!(std::fs::read_to_string(last).expect("r"), LID_SCENE);
}

#[test]
fn depth_files_read_back_and_missing_ones_are_reported() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    let mut m: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.path().join("capture.json")).expect("r"))
            .expect("json");
    m["depth"] = serde_json::json!("pi3x");
    m["depth_scale"] = serde_json::json!(0.001);
    std::fs::write(dir.path().join("capture.json"), m.to_string()).expect("w");
    assert!(problems(dir.path()).contains("has no depth/000000.npz or .png"));
    // Frame 000000: a point map at half resolution with a rejected column; 000010: a PNG in mm.
    let (dw, dh) = (W as usize / 2, H as usize / 2);
    let mut local = Vec::new();
    let mut keep = Vec::new();
    for _y in 0..dh {
        for x in 0..dw {
            local.extend([0.0f32, 0.0, 1.5 + 0.01 * x as f32]);
            keep.push(if x == 0 { 0i64 } else { 1 });
        }
    }
    std::fs::create_dir_all(dir.path().join("depth")).expect("dir");
    agentstar_data::npz::write_arrays(
        &dir.path().join("depth/000000.npz"),
        &[("local", &[dh, dw, 3], &local)],
        &[("keep", &[dh, dw], &keep)],
    )
    .expect("npz");
    let png = image::ImageBuffer::<image::Luma<u16>, Vec<u16>>::from_fn(W, H, |x, _| {
        image::Luma([if x == 0 { 0 } else { 1200 }])
    });
    png.save(dir.path().join("depth/000010.png")).expect("png");
    assert!(
        Capture::validate(dir.path()).is_empty(),
        "{}",
        problems(dir.path())
    );
    let c = Capture::open(dir.path()).expect("open");
    let d0 = c.load_depth(0).expect("read").expect("depth");
    assert_eq!((d0.width, d0.height), (W, H));
    assert!(
        d0.depth[0].is_nan() && d0.depth[1].is_nan(),
        "kept=false pixels are invalid"
    );
    assert!((d0.depth[3] - 1.51).abs() < 1e-6, "{}", d0.depth[3]);
    let d1 = c.load_depth(1).expect("read").expect("depth");
    assert!(d1.depth[0].is_nan());
    assert!((d1.depth[1] - 1.2).abs() < 1e-6);
}

/// A drawer cabinet with a door on a chain: exercises revolute, prismatic and chained parts.
const CHAIN_SCENE: &str = r#"
part("cabinet", box(0.6, 0.5, 0.8) - box(0.5, 0.5, 0.3).translate(0, -0.06, 0.15));
part("drawer", box(0.48, 0.44, 0.28).translate(0, -0.03, 0.15));
part("knob", cylinder(0.03, 0.04).rotate_x(90).translate(0, -0.27, 0.15));
part("door", box(0.5, 0.02, 0.3).translate(0, -0.26, -0.2));
joint(#{ name: "slide", type: "prismatic", child: "drawer", axis: [0, -1, 0], limit: [0, 0.4] });
joint(#{ name: "twist", type: "continuous", child: "knob", parent: "slide", origin: [0, -0.27, 0.15], axis: [0, -1, 0] });
joint(#{ name: "door_hinge", type: "revolute", child: "door", origin: [-0.25, -0.26, -0.2], axis: [0, 0, -1], limit: [0, 120] });
"#;

#[test]
fn the_animated_glb_round_trips_poses_and_joints() {
    use agentstar_data::animation::{animated_glb_bytes, read_animated_glb, AnimFrame};
    use agentstar_geom::pose::Similarity;
    let model = agentstar_scene::build_scene(
        CHAIN_SCENE,
        &agentstar_scene::NoMeshFiles,
        &agentstar_scene::Limits::default(),
    )
    .expect("scene")
    .model;
    let frames: Vec<AnimFrame> = (0..6)
        .map(|k| {
            let t = k as f64;
            AnimFrame {
                name: format!("{:06}.png", 5 * k),
                time_s: t / 6.0,
                world_from_object: Similarity {
                    scale: 0.7,
                    rotation: UnitQuaternion::from_euler_angles(0.3 * t, -0.2 * t, 1.0 + 0.1 * t),
                    translation: Vector3::new(0.1 * t, -0.05, 1.5 + 0.02 * t),
                },
                states: vec![0.05 * t, 0.4 * t, (15.0 * t).to_radians()],
            }
        })
        .collect();
    let bytes = animated_glb_bytes(&model, &frames).expect("glb");
    let read = read_animated_glb(&bytes, Path::new("mem.glb")).expect("reads back and validates");
    assert_eq!(read.frames.len(), 6);
    assert_eq!(read.frames[3], "000015.png");
    for (k, f) in frames.iter().enumerate() {
        let w = &read.world_from_object[k];
        assert!((w.scale - 0.7).abs() < 1e-6);
        assert!(
            w.rotation.angle_to(&f.world_from_object.rotation) < 1e-5,
            "frame {k}"
        );
        assert!((w.translation - f.world_from_object.translation).norm() < 1e-5);
        let fk = model.tree.part_transforms(&f.states);
        for (i, p) in model.parts.iter().enumerate() {
            let got = &read.parts[&p.name][k];
            assert!(
                got.rotation.angle_to(&fk[i].rotation) < 1e-5,
                "{} frame {k}",
                p.name
            );
            assert!((got.translation.vector - fk[i].translation.vector).norm() < 1e-5);
        }
    }
    // Joint states come back exactly, in interface units.
    assert!((read.joint_states["door_hinge"][4] - 60.0).abs() < 1e-9);
    assert!((read.joint_states["slide"][2] - 0.1).abs() < 1e-12);
    // The rest of the file is an ordinary GLB: every part is a mesh node.
    let parts = parse_glb(&bytes).expect("meshes");
    assert_eq!(parts.len(), 1, "one root node holding the parts");
    // Times must increase, poses must be finite.
    let mut bad = frames.clone();
    bad[2].time_s = bad[1].time_s;
    assert!(animated_glb_bytes(&model, &bad)
        .expect_err("times")
        .contains("increase"));
    let mut bad = frames.clone();
    bad[1].world_from_object.translation.x = f64::NAN;
    assert!(animated_glb_bytes(&model, &bad)
        .expect_err("nan")
        .contains("000005.png"));
}

/// Issue 16's silent misreads: each is now an error naming the file and the field.
#[test]
fn camera_sizes_bottom_rows_and_keyframes_are_checked() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(
        dir.path(),
        3,
        vec![identity(), translated(0.1), translated(0.2)],
    );
    let cams_path = dir.path().join("tracking/cameras.json");
    let cams_text = std::fs::read_to_string(&cams_path).expect("cams");
    let set = |f: &dyn Fn(&mut serde_json::Value)| {
        let mut v: serde_json::Value = serde_json::from_str(&cams_text).expect("json");
        f(&mut v);
        std::fs::write(&cams_path, v.to_string()).expect("write");
    };
    for size in [
        serde_json::json!([0, 0]),
        serde_json::json!([-1, -1]),
        serde_json::json!([640, 480, 3]),
    ] {
        set(&|v| v["size"] = size.clone());
        let p = problems(dir.path());
        assert!(
            p.contains("cameras.json") && p.contains("size"),
            "{size}: {p}"
        );
    }
    set(&|v| v["c2w"][1][3] = serde_json::json!([1.0, 2.0, 3.0, 4.0]));
    let p = problems(dir.path());
    assert!(p.contains("c2w[1]") && p.contains("bottom row"), "{p}");
    std::fs::write(&cams_path, &cams_text).expect("restore");
    // The same in cameras.npz, where `size` is an array of any shape and value.
    std::fs::remove_file(&cams_path).expect("rm");
    let npz = dir.path().join("tracking/cameras.npz");
    let c2w: Vec<f32> = [identity(), translated(0.1), translated(0.2)]
        .iter()
        .flat_map(|m| m.iter().flatten().map(|&v| v as f32).collect::<Vec<_>>())
        .collect();
    let k: Vec<f32> = (0..3)
        .flat_map(|_| [50.0, 0.0, 20.0, 0.0, 50.0, 15.0, 0.0, 0.0, 1.0])
        .collect();
    for size in [vec![0i64, 0], vec![-1, -1], vec![640, 480, 3]] {
        agentstar_data::npz::write_arrays(
            &npz,
            &[("c2w", &[3, 4, 4], &c2w), ("intrinsics", &[3, 3, 3], &k)],
            &[("size", &[size.len()], &size)],
        )
        .expect("npz");
        let p = problems(dir.path());
        assert!(
            p.contains("cameras.npz") && p.contains("`size`"),
            "{size:?}: {p}"
        );
    }
    agentstar_data::npz::write_arrays(
        &npz,
        &[("c2w", &[3, 4, 4], &c2w), ("intrinsics", &[3, 3, 3], &k)],
        &[("size", &[2], &[W as i64, H as i64])],
    )
    .expect("npz");
    assert!(
        Capture::validate(dir.path()).is_empty(),
        "{}",
        problems(dir.path())
    );
}

#[test]
fn pose_and_ground_truth_values_that_cannot_be_used_are_errors() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("pose.json");
    let pose = |q: &str, scale: &str| {
        format!(
            r#"{{"scale": 0.2, "reference_frame": "a", "frames": {{"a": {{"object_pose": {{"quaternion": {q}, "translation": [0,0,1]{scale}}}}}}}}}"#
        )
    };
    std::fs::write(&p, pose("[1e300, 1e300, 0, 0]", "")).expect("w");
    let e = PoseFile::read(&p).expect_err("overflow").to_string();
    assert!(e.contains("pose.json") && e.contains("quaternion"), "{e}");
    for scale in ["0", "-0.2", "1e300"] {
        std::fs::write(&p, pose("[1, 0, 0, 0]", &format!(", \"scale\": {scale}"))).expect("w");
        let e = PoseFile::read(&p).expect_err("scale").to_string();
        assert!(e.contains("object_pose.scale"), "{scale}: {e}");
    }
    std::fs::write(&p, pose("[1, 0, 0, 0]", ", \"scale\": 0.2")).expect("w");
    PoseFile::read(&p).expect("the shared scale repeated is fine");
    std::fs::write(&p, pose("[1, NaN, 0, 0]", "")).expect("w");
    let e = PoseFile::read(&p).expect_err("nan").to_string();
    assert!(e.contains("`NaN`"), "{e}");
    // gt.json: a quaternion that overflows and a zero joint axis.
    let mesh = agentstar_geom::primitives::cuboid(0.1, 0.1, 0.1).expect("box");
    std::fs::write(
        dir.path().join("m.obj"),
        agentstar_data::meshio::obj_text(&mesh, "m"),
    )
    .expect("w");
    let gt = dir.path().join("gt.json");
    let write_gt = |q: &str, axis: &str| {
        std::fs::write(&gt, format!(r#"{{"format": "agentstar-gt/1", "base_part": "a", "parts": {{"a": {{"mesh": "m.obj"}}, "b": {{"mesh": "m.obj"}}}},
            "frames": {{"000000": {{"parts": {{"a": {{"quaternion": {q}, "translation": [0, 0, 1]}}}}}}}},
            "joints": [{{"name": "h", "type": "revolute", "parent": "a", "child": "b", "axis": {axis}}}]}}"#)).expect("w");
    };
    write_gt("[1e300, 1e300, 0, 0]", "[1, 0, 0]");
    let e = agentstar_data::gt::GroundTruth::load(&gt)
        .expect_err("quaternion")
        .to_string();
    assert!(e.contains("gt.json") && e.contains("quaternion"), "{e}");
    write_gt("[1, 0, 0, 0]", "[0, 0, 0]");
    let e = agentstar_data::gt::GroundTruth::load(&gt)
        .expect_err("axis")
        .to_string();
    assert!(e.contains("joint `h`") && e.contains("axis"), "{e}");
    write_gt("[1, 0, 0, 0]", "[0, 0, 1]");
    agentstar_data::gt::GroundTruth::load(&gt).expect("valid ground truth");
}

#[test]
fn urdf_loops_duplicates_and_zero_axes_are_named() {
    let dir = tempfile::tempdir().expect("tmp");
    let p = dir.path().join("r.urdf");
    let link = |n: &str| {
        format!("<link name=\"{n}\"><visual><geometry><box size=\"1 1 0.2\"/></geometry></visual></link>")
    };
    let joint = |n: &str, p: &str, c: &str, axis: &str| {
        format!("<joint name=\"{n}\" type=\"continuous\"><parent link=\"{p}\"/><child link=\"{c}\"/><axis xyz=\"{axis}\"/></joint>")
    };
    let cases = [
        (
            format!(
                "{}{}{}{}{}{}",
                link("root"),
                link("base"),
                link("lid"),
                joint("j0", "root", "base", "1 0 0"),
                joint("j1", "base", "lid", "1 0 0"),
                joint("back", "lid", "base", "1 0 0")
            ),
            "kinematic loop",
        ),
        (
            format!("{}{}", link("base"), link("base")),
            "link `base` is defined twice",
        ),
        (
            format!(
                "{}{}{}{}",
                link("a"),
                link("b"),
                joint("j", "a", "b", "1 0 0"),
                joint("j", "a", "b", "1 0 0")
            ),
            "joint `j` is defined twice",
        ),
        (
            format!(
                "{}{}{}",
                link("a"),
                link("b"),
                joint("j", "a", "b", "0 0 0")
            ),
            "zero vector",
        ),
    ];
    for (body, expect) in cases {
        std::fs::write(&p, format!("<robot name=\"r\">{body}</robot>")).expect("w");
        let e = load_urdf(&p).expect_err(expect).to_string();
        assert!(e.contains("r.urdf") && e.contains(expect), "{expect}: {e}");
    }
}

/// `as_stored` is exactly what a reader of a written capture gets (the bench relies on it to
/// measure what `track` gets from the files), and it does round: float32 is not float64.
#[test]
fn a_written_captures_cameras_read_back_exactly_as_as_stored_says() {
    use agentstar_data::capture_writer::{as_stored, write_capture, CaptureInfo, FrameOut};
    use agentstar_geom::pose::Rigid;
    use agentstar_geom::PinholeCamera;
    use agentstar_mask::BitMask;
    use nalgebra::Translation3;
    let dir = tempfile::tempdir().expect("tmp");
    let camera = PinholeCamera::new(611.123456789, 612.987654321, 338.3, 229.7, W, H).expect("cam");
    let poses: Vec<Rigid> = (0..3)
        .map(|k| {
            let k = f64::from(k);
            Rigid::from_parts(
                Translation3::new(0.1 + k / 3.0, -0.2 / 7.0, 0.35 + k / 11.0),
                UnitQuaternion::from_euler_angles(0.3 + k, -1.1 / 3.0, 2.0 * k / 7.0),
            )
        })
        .collect();
    let rgb = RgbImage::from_pixel(W, H, image::Rgb([90, 90, 90]));
    let mask = BitMask::from_fn(W, H, |x, _| x < 20);
    let names: Vec<String> = (0..3).map(|k| format!("{:06}.png", k * 10)).collect();
    let frames: Vec<FrameOut<'_>> = poses
        .iter()
        .zip(&names)
        .enumerate()
        .map(|(k, (pose, name))| FrameOut {
            name,
            frame_index: Some(10 * k as i64),
            time_s: None,
            camera: &camera,
            world_from_camera: pose,
            rgb: &rgb,
            mask: &mask,
            hand: None,
            depth_m: None,
        })
        .collect();
    let out = dir.path().join("cap");
    write_capture(&out, &frames, &CaptureInfo::default(), |_| Ok(())).expect("write");
    let capture = Capture::open(&out).expect("open");
    for (frame, pose) in capture.frames.iter().zip(&poses) {
        let (stored_camera, stored_pose) = as_stored(&camera, pose).expect("as stored");
        assert_eq!(frame.camera, stored_camera, "{}", frame.name);
        assert_eq!(frame.world_from_camera, stored_pose, "{}", frame.name);
        assert_ne!(
            stored_pose, *pose,
            "{}: float32 must round this pose",
            frame.name
        );
    }
    assert_ne!(capture.frames[0].camera.fx, camera.fx, "float32 rounds fx");
}
