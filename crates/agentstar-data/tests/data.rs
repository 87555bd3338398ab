//! File formats end to end: a capture written by the test is read back; every kind of bad
//! input gets its own message naming the file; pose files, URDF and exports round-trip.

use agentstar_data::capture::{CamerasJson, Capture, Keyframe, Manifest};
use agentstar_data::export::{glb_bytes, write_glb, write_urdf};
use agentstar_data::meshio::parse_glb;
use agentstar_data::posefile::PoseFile;
use agentstar_data::scenefile::{load_model, load_scene_script, ScriptDirMeshes};
use agentstar_data::urdf::load_urdf;
use agentstar_geom::pose::ObjectPose;
use agentstar_geom::{Point3, UnitQuaternion, Vector3};
use agentstar_scene::MeshSource;
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

fn problems_of(dir: &Path) -> String {
    Capture::validate(dir)
        .iter()
        .map(|p| p.to_string())
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn missing_mask_is_named() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    std::fs::remove_file(dir.path().join("mask_object/000010.png")).expect("rm");
    let p = problems_of(dir.path());
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
    let p = problems_of(dir.path());
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
    let p = problems_of(dir.path());
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
    let p = problems_of(dir.path());
    assert!(p.contains("unknown format \"capture/v9\""), "{p}");
    assert!(
        p.contains("frame `frame_a.jpg`: the file stem must be a zero-padded integer"),
        "{p}"
    );
}

#[test]
fn missing_manifest_cameras_and_corrupt_files() {
    let dir = tempfile::tempdir().expect("tmp");
    assert!(problems_of(&dir.path().join("nope")).contains("does not exist"));
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    std::fs::remove_file(dir.path().join("tracking/cameras.json")).expect("rm");
    assert!(problems_of(dir.path()).contains("no cameras"));
    std::fs::write(dir.path().join("tracking/cameras.npz"), b"garbage").expect("w");
    assert!(
        problems_of(dir.path()).contains("cameras.npz: not a readable .npz archive"),
        "{}",
        problems_of(dir.path())
    );
    std::fs::write(dir.path().join("capture.json"), "{ not json").expect("w");
    assert!(problems_of(dir.path()).contains("capture.json: invalid manifest"));
}

#[test]
fn keyframe_view_out_of_range() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(dir.path(), 2, vec![identity(), identity()]);
    let kf =
        r#"[{"view": 0, "frame_name": "000000.jpg"}, {"view": 7, "frame_name": "000010.jpg"}]"#;
    std::fs::write(dir.path().join("tracking/keyframes.json"), kf).expect("w");
    let p = problems_of(dir.path());
    assert!(p.contains("view 7 is out of range"), "{p}");
}

const LID_SCENE: &str = r#"
part("base", box(1, 0.6, 0.2));
part("lid", box(1, 0.6, 0.05).translate(0, 0, 0.125));
joint(#{ name: "hinge", type: "revolute", child: "lid", origin: [0, 0.3, 0.1], axis: [1, 0, 0], limit: [0, 120] });
"#;

#[test]
fn pose_file_resolution_seeds_through_cameras_and_checks_joints() {
    let dir = tempfile::tempdir().expect("tmp");
    write_capture(
        dir.path(),
        3,
        vec![identity(), translated(0.1), translated(0.2)],
    );
    let cap = Capture::open(dir.path()).expect("open");
    std::fs::write(dir.path().join("scene.rhai"), LID_SCENE).expect("w");
    let model = load_model(&dir.path().join("scene.rhai"))
        .expect("model")
        .model;
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
    assert!((resolved[0].pose.translation - Vector3::new(0.2, 0.0, 2.0)).norm() < 1e-9);
    assert!((resolved[0].states[0] - 30f64.to_radians()).abs() < 1e-12);
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
    assert!(problems_of(dir.path()).contains("has no depth/000000.npz or .png"));
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
        problems_of(dir.path())
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

/// Writes a small BOP scene: a 60 × 40 × 30 mm box (object 3) and a second object
/// (object 7) partly in front of it, seen by a moving camera in three images, with masks,
/// 16-bit depth and models_info symmetries.
fn write_bop_scene(
    root: &Path,
) -> (
    Vec<agentstar_geom::pose::ObjectPose>,
    agentstar_geom::PinholeCamera,
) {
    use agentstar_geom::pose::ObjectPose;
    use agentstar_render::raster::Affine;
    use agentstar_render::{render_full, Instance};
    let scene = root.join("scene");
    let models = root.join("models");
    std::fs::create_dir_all(scene.join("rgb")).expect("mkdir");
    std::fs::create_dir_all(scene.join("mask_visib")).expect("mkdir");
    std::fs::create_dir_all(scene.join("depth")).expect("mkdir");
    std::fs::create_dir_all(&models).expect("mkdir");
    let mm = agentstar_geom::primitives::cuboid(60.0, 40.0, 30.0).expect("box");
    let mut ply = format!(
        "ply\nformat ascii 1.0\nelement vertex {}\nproperty float x\nproperty float y\nproperty float z\nelement face {}\nproperty list uchar int vertex_indices\nend_header\n",
        mm.positions.len(),
        mm.triangles.len()
    );
    for p in &mm.positions {
        ply.push_str(&format!("{} {} {}\n", p.x, p.y, p.z));
    }
    for t in &mm.triangles {
        ply.push_str(&format!("3 {} {} {}\n", t[0], t[1], t[2]));
    }
    std::fs::write(models.join("obj_000003.ply"), ply).expect("ply");
    std::fs::write(
        models.join("models_info.json"),
        r#"{"3": {"diameter": 78.1, "symmetries_discrete": [[-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]]}}"#,
    )
    .expect("info");
    let cam = agentstar_geom::PinholeCamera::new(300.0, 300.0, 80.0, 60.0, 160, 120).expect("cam");
    let m_box = mm.transformed(
        &(agentstar_geom::Matrix3::identity() * 0.001),
        &Vector3::zeros(),
    );
    let blocker = agentstar_geom::primitives::cuboid(0.02, 0.02, 0.02).expect("blocker");
    let mut poses = vec![];
    let (mut gt, mut cams) = (serde_json::Map::new(), serde_json::Map::new());
    for id in [0u32, 2, 4] {
        let k = id as f64;
        let pose = ObjectPose::new(
            UnitQuaternion::from_euler_angles(0.4 + 0.1 * k, -0.3, 0.2 * k),
            Vector3::new(0.005 * k, -0.004, 0.4),
        );
        let other = ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.02, 0.01, 0.3));
        let inst = |m: &'static agentstar_geom::TriMesh, p: &ObjectPose, id: u16| Instance {
            mesh: m,
            bounds: m.bounds(),
            camera_from_mesh: Affine::from_similarity(&p.with_scale(1.0)),
            edges: None,
            part_id: id,
        };
        let m_box: &'static agentstar_geom::TriMesh = Box::leak(Box::new(m_box.clone()));
        let b: &'static agentstar_geom::TriMesh = Box::leak(Box::new(blocker.clone()));
        let buf = render_full(&cam, &[inst(m_box, &pose, 0), inst(b, &other, 1)]);
        let stem = format!("{id:06}");
        let rgb = RgbImage::from_fn(160, 120, |x, y| {
            image::Rgb([
                (x % 256) as u8,
                (y % 256) as u8,
                if buf.covered(x, y) { 200 } else { 40 },
            ])
        });
        rgb.save(scene.join("rgb").join(format!("{stem}.png")))
            .expect("rgb");
        for (i, part) in [0u16, 1].iter().enumerate() {
            let m = GrayImage::from_fn(160, 120, |x, y| {
                Luma([if buf.part[(y * 160 + x) as usize] == *part {
                    255
                } else {
                    0
                }])
            });
            m.save(scene.join("mask_visib").join(format!("{stem}_{i:06}.png")))
                .expect("mask");
        }
        let depth = image::ImageBuffer::<Luma<u16>, Vec<u16>>::from_fn(160, 120, |x, y| {
            let z = buf.depth[(y * 160 + x) as usize];
            Luma([if z.is_finite() {
                (z * 10_000.0) as u16
            } else {
                0
            }])
        });
        depth
            .save(scene.join("depth").join(format!("{stem}.png")))
            .expect("depth");
        let r = pose.rotation.to_rotation_matrix();
        let rm: Vec<f64> = (0..3)
            .flat_map(|i| (0..3).map(move |j| r[(i, j)]))
            .collect();
        gt.insert(
            id.to_string(),
            serde_json::json!([
                {"cam_R_m2c": rm, "cam_t_m2c": [pose.translation.x * 1000.0, pose.translation.y * 1000.0, pose.translation.z * 1000.0], "obj_id": 3},
                {"cam_R_m2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_m2c": [20, 10, 300], "obj_id": 7}
            ]),
        );
        cams.insert(
            id.to_string(),
            serde_json::json!({"cam_K": [300, 0, 80, 0, 300, 60, 0, 0, 1], "depth_scale": 0.1,
                               "cam_R_w2c": [1, 0, 0, 0, 1, 0, 0, 0, 1], "cam_t_w2c": [-10.0 * k, 0, 0]}),
        );
        poses.push(pose);
    }
    std::fs::write(
        scene.join("scene_gt.json"),
        serde_json::Value::Object(gt).to_string(),
    )
    .expect("gt");
    std::fs::write(
        scene.join("scene_camera.json"),
        serde_json::Value::Object(cams).to_string(),
    )
    .expect("cam");
    (poses, cam)
}

#[test]
fn a_bop_scene_imports_with_metres_occluders_depth_and_ground_truth() {
    use agentstar_data::bop::{import_bop, BopImport};
    use agentstar_data::gt::GroundTruth;
    let dir = tempfile::tempdir().expect("tmp");
    let (poses, cam) = write_bop_scene(dir.path());
    let out = dir.path().join("cap");
    let cfg = BopImport {
        scene: dir.path().join("scene"),
        models: dir.path().join("models"),
        obj_id: 3,
        every: 1,
        depth: true,
    };
    assert_eq!(import_bop(&cfg, &out).expect("import"), 3);
    let capture = Capture::open(&out).expect("valid capture");
    assert_eq!(capture.frames.len(), 3);
    assert_eq!(capture.frames[1].name, "000002.png");
    // The camera trajectory in metres: camera k sits 10·k mm along +X.
    assert!((capture.frames[2].world_from_camera.translation.vector.x - 0.04).abs() < 1e-9);
    // The other object is a don't-care occluder; depth is in metres.
    let hand = capture.load_hand(0).expect("read").expect("occluder mask");
    assert!(hand.count() > 0);
    let depth = capture.load_depth(0).expect("read").expect("depth");
    let mask = capture.load_mask(0).expect("mask");
    let (x, y) = (0..160u32)
        .flat_map(|x| (0..120u32).map(move |y| (x, y)))
        .find(|&(x, y)| mask.get(x, y))
        .expect("object pixel");
    let z = depth.depth[(y * 160 + x) as usize];
    assert!((z - 0.39).abs() < 0.03, "depth {z} m");
    // gt.json: the model in metres, poses in metres, the discrete symmetry.
    let gt = GroundTruth::load(&out.join("gt.json")).expect("gt");
    let ext = gt.meshes["object"].bounds().extent();
    assert!(
        (ext.x - 0.06).abs() < 1e-6 && (ext.z - 0.03).abs() < 1e-6,
        "{ext:?}"
    );
    let p = gt.pose("000004.png", "object").expect("pose");
    assert!((p.translation - poses[2].translation).norm() < 1e-9);
    assert!(p.rotation.angle_to(&poses[2].rotation) < 1e-6);
    assert_eq!(gt.file.symmetries.len(), 1);
    assert!(
        gt.file.symmetries[0][3].abs() > 0.999,
        "a half turn about Z"
    );
    // Rendering the ground truth gives back the visible mask outside the occluder.
    let inst = agentstar_render::Instance {
        mesh: &gt.meshes["object"],
        bounds: gt.meshes["object"].bounds(),
        camera_from_mesh: agentstar_render::raster::Affine::from_similarity(&p.with_scale(1.0)),
        edges: None,
        part_id: 0,
    };
    let sil = agentstar_render::render_full(&cam, &[inst]).silhouette();
    let m2 = capture.load_mask(2).expect("mask");
    let h2 = capture.load_hand(2).expect("hand").expect("occluder");
    assert_eq!(sil.and_not(&h2).count(), m2.count());
    // Bad input is named.
    let e = import_bop(
        &BopImport {
            obj_id: 9,
            ..cfg.clone()
        },
        &dir.path().join("x"),
    )
    .expect_err("absent");
    assert!(e.to_string().contains("obj_000009.ply"), "{e}");
    assert!(!dir.path().join("x").exists());
}

/// Frames and masks in folders (segmenter-style names), and the same three cameras written
/// as COLMAP text, COLMAP binary and nerfstudio: each import gives back the cameras.
#[test]
fn frames_with_colmap_binary_text_and_nerfstudio_cameras_import() {
    use agentstar_data::video::{import_video, CameraSource, VideoImport};
    use agentstar_geom::pose::Rigid;
    let dir = tempfile::tempdir().expect("tmp");
    let (frames, masks) = (dir.path().join("frames"), dir.path().join("masks"));
    std::fs::create_dir_all(&frames).expect("mkdir");
    std::fs::create_dir_all(&masks).expect("mkdir");
    let (w, h) = (64u32, 48u32);
    let mut truth: Vec<Rigid> = vec![];
    for i in 0..3u32 {
        RgbImage::from_pixel(w, h, image::Rgb([10 * i as u8, 90, 160]))
            .save(frames.join(format!("img_{i}.jpg")))
            .expect("frame");
        GrayImage::from_fn(w, h, |x, y| {
            Luma([if x > 20 + i && y > 10 { 255 } else { 0 }])
        })
        .save(masks.join(format!("img_{i}_mask.png")))
        .expect("mask");
        truth.push(Rigid::from_parts(
            agentstar_geom::nalgebra::Translation3::new(0.1 * i as f64, -0.2, 0.05),
            UnitQuaternion::from_euler_angles(0.1 * i as f64, 0.3, -0.2),
        ));
    }
    // COLMAP stores camera_from_world for a 128 × 96 camera (frames are half that size).
    let (colmap_txt, colmap_bin) = (dir.path().join("txt"), dir.path().join("bin"));
    std::fs::create_dir_all(&colmap_txt).expect("mkdir");
    std::fs::create_dir_all(&colmap_bin).expect("mkdir");
    std::fs::write(
        colmap_txt.join("cameras.txt"),
        "# Camera list\n1 PINHOLE 128 96 100 110 64 48\n",
    )
    .expect("cameras");
    let mut images = String::from("# Image list\n");
    let mut bin_images: Vec<u8> = 3u64.to_le_bytes().to_vec();
    for (i, c2w) in truth.iter().enumerate() {
        let cfw = c2w.inverse();
        let q = cfw.rotation;
        let t = cfw.translation.vector;
        images.push_str(&format!(
            "{} {} {} {} {} {} {} {} 1 img_{i}.jpg\n\n",
            i + 1,
            q.w,
            q.i,
            q.j,
            q.k,
            t.x,
            t.y,
            t.z
        ));
        bin_images.extend((i as i32 + 1).to_le_bytes());
        for v in [q.w, q.i, q.j, q.k, t.x, t.y, t.z] {
            bin_images.extend(v.to_le_bytes());
        }
        bin_images.extend(1i32.to_le_bytes());
        bin_images.extend(format!("img_{i}.jpg\0").bytes());
        bin_images.extend(1u64.to_le_bytes());
        bin_images.extend([0u8; 24]);
    }
    std::fs::write(colmap_txt.join("images.txt"), images).expect("images");
    let mut bin_cams: Vec<u8> = 1u64.to_le_bytes().to_vec();
    bin_cams.extend(1i32.to_le_bytes());
    bin_cams.extend(1i32.to_le_bytes()); // PINHOLE
    bin_cams.extend(128u64.to_le_bytes());
    bin_cams.extend(96u64.to_le_bytes());
    for v in [100.0f64, 110.0, 64.0, 48.0] {
        bin_cams.extend(v.to_le_bytes());
    }
    std::fs::write(colmap_bin.join("cameras.bin"), bin_cams).expect("cameras.bin");
    std::fs::write(colmap_bin.join("images.bin"), bin_images).expect("images.bin");
    // nerfstudio: world_from_camera in OpenGL axes.
    let ns = dir.path().join("transforms.json");
    let flip = agentstar_geom::Matrix4::from_diagonal(&agentstar_geom::nalgebra::Vector4::new(
        1.0, -1.0, -1.0, 1.0,
    ));
    let ns_frames: Vec<_> = truth
        .iter()
        .enumerate()
        .map(|(i, c2w)| {
            let m = c2w.to_homogeneous() * flip;
            serde_json::json!({"file_path": format!("images/img_{i}.jpg"),
                "transform_matrix": (0..4).map(|r| (0..4).map(|c| m[(r, c)]).collect::<Vec<_>>()).collect::<Vec<_>>()})
        })
        .collect();
    std::fs::write(
        &ns,
        serde_json::json!({"fl_x": 100.0, "fl_y": 110.0, "cx": 64.0, "cy": 48.0, "w": 128, "h": 96, "frames": ns_frames}).to_string(),
    )
    .expect("ns");
    for (label, cameras) in [
        ("txt", CameraSource::Colmap(colmap_txt.clone())),
        ("bin", CameraSource::Colmap(colmap_bin.clone())),
        ("ns", CameraSource::Nerfstudio(ns.clone())),
    ] {
        let out = dir.path().join(format!("cap_{label}"));
        let n = import_video(
            &VideoImport {
                input: frames.clone(),
                masks: masks.clone(),
                hands: None,
                every: 1,
                max_frames: None,
                cameras,
                fps: Some(10.0),
            },
            &out,
        )
        .unwrap_or_else(|e| panic!("{label}: {e}"));
        assert_eq!(n, 3);
        let cap = Capture::open(&out).expect("valid");
        for (i, f) in cap.frames.iter().enumerate() {
            let c = &f.world_from_camera;
            assert!(
                (c.translation.vector - truth[i].translation.vector).norm() < 1e-6,
                "{label} {i}"
            );
            assert!(
                c.rotation.angle_to(&truth[i].rotation) < 1e-6,
                "{label} {i}"
            );
            // Intrinsics rescaled to the 64 × 48 frames.
            assert!((f.camera.fx - 50.0).abs() < 1e-6 && (f.camera.fy - 55.0).abs() < 1e-6);
            assert!((f.camera.cx - 32.0).abs() < 1e-6 && (f.camera.cy - 24.0).abs() < 1e-6);
        }
        assert_eq!(
            cap.load_mask(2).expect("mask").count(),
            (64 - 23) * (48 - 11)
        );
        assert!((cap.frames[2].time_s.expect("time") - 0.2).abs() < 1e-12);
    }
    // A static camera by field of view; a missing mask and a truncated model are named.
    let out = dir.path().join("cap_fov");
    let cfg = VideoImport {
        input: frames.clone(),
        masks: masks.clone(),
        hands: None,
        every: 2,
        max_frames: None,
        cameras: CameraSource::Fov(60.0),
        fps: None,
    };
    assert_eq!(import_video(&cfg, &out).expect("fov"), 2);
    std::fs::remove_file(masks.join("img_2_mask.png")).expect("rm");
    let e = import_video(&cfg, &dir.path().join("x")).expect_err("missing mask");
    assert!(e.to_string().contains("img_2"), "{e}");
    let bytes = std::fs::read(colmap_bin.join("images.bin")).expect("read");
    std::fs::write(colmap_bin.join("images.bin"), &bytes[..bytes.len() - 30]).expect("truncate");
    let e = agentstar_data::cameras::read_colmap(&colmap_bin).expect_err("truncated");
    assert!(
        e.to_string().contains("images.bin") && e.to_string().contains("truncated"),
        "{e}"
    );
}

/// Centroid of a mask, in pixels.
fn mask_centroid(m: &agentstar_render::BitMask) -> (f64, f64) {
    let (mut sx, mut sy, mut n) = (0.0, 0.0, 0.0);
    for y in 0..m.height() {
        for x in 0..m.width() {
            if m.get(x, y) {
                sx += x as f64 + 0.5;
                sy += y as f64 + 0.5;
                n += 1.0;
            }
        }
    }
    assert!(n > 0.0, "empty mask");
    (sx / n, sy / n)
}

fn rigid(axis: [f64; 3], angle_deg: f64, t: [f64; 3]) -> agentstar_geom::pose::Rigid {
    agentstar_geom::pose::Rigid::from_parts(
        Vector3::new(t[0], t[1], t[2]).into(),
        UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(axis[0], axis[1], axis[2])),
            angle_deg.to_radians(),
        ),
    )
}

fn csv_row(uid: &str, t: u64, p: &agentstar_geom::pose::Rigid) -> String {
    let q = p.rotation;
    let v = p.translation.vector;
    // Columns in an order other than the documented one: found by name.
    format!(
        "{},{},{},{},{},{},{},{},{}\n",
        t, uid, q.w, q.i, q.j, q.k, v.x, v.y, v.z
    )
}

#[test]
fn a_hot3d_sequence_imports_with_headset_cameras_and_nearest_poses() {
    use agentstar_data::hot3d::{import_hot3d, Hot3dImport};
    let dir = tempfile::tempdir().expect("tmp");
    let root = dir.path();
    let seq = root.join("seq");
    let models = root.join("object_models");
    let frames = root.join("frames");
    for d in [&seq, &models, &frames] {
        std::fs::create_dir_all(d).expect("mkdir");
    }
    // A 12 × 6 × 4 cm box written as the object library's GLB.
    std::fs::write(
        root.join("s.rhai"),
        "part(\"body\", box(0.12, 0.06, 0.04));",
    )
    .expect("w");
    let model = load_scene_script(&root.join("s.rhai"), &Default::default())
        .expect("model")
        .model;
    std::fs::write(models.join("1234.glb"), glb_bytes(&model)).expect("glb");
    let header =
        "timestamp[ns],object_uid,q_wo_w,q_wo_x,q_wo_y,q_wo_z,t_wo_x[m],t_wo_y[m],t_wo_z[m]\n";
    let device_from_camera = rigid([0.0, 1.0, 0.0], 5.0, [0.01, -0.02, 0.0]);
    let (mut objects, mut headset) = (header.to_string(), header.to_string());
    let mut truth = vec![];
    for k in 0..4u64 {
        let t = 1_000_000_000 + k * 33_333_333;
        let world_from_object = rigid(
            [0.2, 1.0, 0.1],
            20.0 * k as f64,
            [0.05 * k as f64, 0.0, 0.6],
        );
        let world_from_device = rigid([1.0, 0.0, 0.0], 3.0 * k as f64, [0.0, 0.01 * k as f64, 0.0]);
        objects += &csv_row("1234", t, &world_from_object);
        objects += &csv_row("999", t, &rigid([0.0, 0.0, 1.0], 0.0, [9.0, 9.0, 9.0]));
        // Headset poses 2 ms off the frame times: the nearest is taken.
        headset += &csv_row("headset", t + 2_000_000, &world_from_device);
        image::RgbImage::new(64, 48)
            .save(frames.join(format!("{t}.png")))
            .expect("frame");
        truth.push((
            t,
            (world_from_device * device_from_camera).inverse() * world_from_object,
        ));
    }
    std::fs::write(seq.join("dynamic_objects.csv"), &objects).expect("w");
    std::fs::write(seq.join("headset_trajectory.csv"), &headset).expect("w");
    // A frame with no pose near it is skipped and counted.
    image::RgbImage::new(64, 48)
        .save(frames.join("5000000000.png"))
        .expect("frame");
    let cfg = Hot3dImport {
        sequence: seq.clone(),
        models: models.clone(),
        object_uid: "1234".into(),
        frames: frames.clone(),
        masks: None,
        hands: None,
        intrinsics: [60.0, 60.0, 32.0, 24.0],
        device_from_camera,
        max_dt_ns: 5_000_000,
        every: 1,
    };
    let out = root.join("cap");
    let summary = import_hot3d(&cfg, &out).expect("import");
    assert_eq!(
        (summary.frames, summary.skipped, summary.rendered_masks),
        (4, 1, true)
    );
    assert!(
        Capture::validate(&out).is_empty(),
        "{:?}",
        Capture::validate(&out)
    );
    let cap = Capture::open(&out).expect("capture");
    let gt = agentstar_data::gt::GroundTruth::load(&out.join("gt.json")).expect("gt");
    let mesh = &gt.meshes["object"];
    let centre = mesh.bounds().center();
    for (t, camera_from_object) in &truth {
        let frame = format!("{t}.png");
        let p = gt.pose(&frame, "object").expect("pose");
        let got = p.to_rigid();
        assert!((got.translation.vector - camera_from_object.translation.vector).norm() < 1e-9);
        assert!(got.rotation.angle_to(&camera_from_object.rotation) < 1e-9);
        // The rendered mask sits where the box centre projects.
        let c = camera_from_object * centre;
        let (u, v) = (60.0 * c.x / c.z + 32.0, 60.0 * c.y / c.z + 24.0);
        let i = cap
            .frames
            .iter()
            .position(|f| f.name == frame)
            .expect("frame");
        let (mx, my) = mask_centroid(&cap.load_mask(i).expect("mask"));
        assert!(
            (mx - u).abs() < 1.5 && (my - v).abs() < 1.5,
            "{mx},{my} vs {u},{v}"
        );
    }
    // A CSV without a column names it.
    std::fs::write(
        seq.join("dynamic_objects.csv"),
        "object_uid,timestamp[ns]\n1,2\n",
    )
    .expect("w");
    let err = import_hot3d(&cfg, &root.join("cap2"))
        .expect_err("bad csv")
        .to_string();
    assert!(
        err.contains("dynamic_objects.csv") && err.contains("t_wo_x[m]"),
        "{err}"
    );
    assert!(!root.join("cap2").exists());
}

/// A `.npy` file (little-endian f8, C order).
fn write_npy(path: &Path, shape: [usize; 2], data: &[f64]) {
    let mut header = format!(
        "{{'descr': '<f8', 'fortran_order': False, 'shape': ({}, {}), }}",
        shape[0], shape[1]
    );
    while (10 + header.len() + 1) % 64 != 0 {
        header.push(' ');
    }
    header.push('\n');
    let mut bytes = b"\x93NUMPY\x01\x00".to_vec();
    bytes.extend((header.len() as u16).to_le_bytes());
    bytes.extend(header.as_bytes());
    for v in data {
        bytes.extend(v.to_le_bytes());
    }
    std::fs::write(path, bytes).expect("npy");
}

#[test]
fn an_arctic_sequence_imports_two_parts_and_the_articulation() {
    use agentstar_data::arctic::{import_arctic, ArcticImport};
    let dir = tempfile::tempdir().expect("tmp");
    let root = dir.path().join("arctic");
    let tpl = root.join("meta/object_vtemplates/box");
    let raw = root.join("raw_seqs/s01");
    let images = root.join("images/s01/box_grab_01/3");
    for d in [&tpl, &raw, &images] {
        std::fs::create_dir_all(d).expect("mkdir");
    }
    // Template in millimetres: a bottom box (z 0..40) and a lid (z 40..50), with texture
    // coordinates so that a reader merging v/vt pairs would reorder the vertices.
    let bottom = agentstar_geom::primitives::cuboid(100.0, 80.0, 40.0).expect("box");
    let lid = agentstar_geom::primitives::cuboid(100.0, 80.0, 10.0).expect("box");
    let mut obj = String::new();
    let mut labels = vec![];
    for (mesh, dz, label) in [(&lid, 45.0, 0), (&bottom, 20.0, 1)] {
        for p in &mesh.positions {
            obj += &format!("v {} {} {}\n", p.x, p.y, p.z + dz);
            labels.push(label);
        }
    }
    obj += "vt 0 0\nvt 1 0\nvt 1 1\n";
    let nl = lid.positions.len() as u32;
    for (mesh, base) in [(&lid, 0), (&bottom, nl)] {
        for t in &mesh.triangles {
            obj += &format!(
                "f {}/1 {}/2 {}/3\n",
                t[0] + base + 1,
                t[1] + base + 1,
                t[2] + base + 1
            );
        }
    }
    std::fs::write(tpl.join("mesh.obj"), obj).expect("w");
    std::fs::write(
        tpl.join("parts.json"),
        serde_json::to_string(&labels).expect("j"),
    )
    .expect("w");
    // Camera 3 of subject s01 (index 2 of world2cam), full images 128 × 96, shown at 64 × 48.
    let w2c = [
        [1.0, 0.0, 0.0, 0.0],
        [0.0, -1.0, 0.0, 0.0],
        [0.0, 0.0, -1.0, 1.0],
        [0.0, 0.0, 0.0, 1.0],
    ];
    let k = [[120.0, 0.0, 64.0], [0.0, 120.0, 48.0], [0.0, 0.0, 1.0]];
    let misc = serde_json::json!({"s01": {
        "world2cam": [w2c, w2c, w2c, w2c, w2c, w2c, w2c, w2c],
        "intris_mat": [k, k, k, k, k, k, k, k],
        "image_size": [[0, 0], [128, 96], [128, 96], [128, 96], [128, 96], [128, 96], [128, 96], [128, 96], [128, 96]],
        "ioi_offset": 2}});
    std::fs::write(root.join("meta/misc.json"), misc.to_string()).expect("w");
    let rows: Vec<[f64; 7]> = (0..6)
        .map(|i| {
            let f = i as f64;
            [0.3 * f, 0.1 * f, -0.2, 0.05 * f, 10.0 * f, -5.0, 20.0 * f]
        })
        .collect();
    write_npy(
        &raw.join("box_grab_01.object.npy"),
        [rows.len(), 7],
        &rows.concat(),
    );
    // Images 00002..00007 hold rows 0..5 (offset 2); 00001 falls before the array.
    for n in 1..=7 {
        image::RgbImage::new(64, 48)
            .save(images.join(format!("{n:05}.jpg")))
            .expect("img");
    }
    let cfg = ArcticImport {
        root: root.clone(),
        subject: "s01".into(),
        sequence: "box_grab_01".into(),
        camera: 3,
        images: None,
        masks: None,
        hands: None,
        offset: None,
        every: 1,
        max_frames: None,
    };
    let out = dir.path().join("cap");
    assert_eq!(import_arctic(&cfg, &out).expect("import"), 6);
    assert!(
        Capture::validate(&out).is_empty(),
        "{:?}",
        Capture::validate(&out)
    );
    let cap = Capture::open(&out).expect("capture");
    let gt = agentstar_data::gt::GroundTruth::load(&out.join("gt.json")).expect("gt");
    assert_eq!(gt.file.base_part, "bottom");
    let joint = &gt.file.joints[0];
    assert_eq!(
        (joint.parent.as_str(), joint.child.as_str()),
        ("bottom", "top")
    );
    assert_eq!(gt.meshes["top"].triangles.len(), lid.triangles.len());
    for n in 2..=7usize {
        let row = rows[n - 2];
        let frame = format!("{n:05}.png");
        assert!((joint.states[&frame] - row[0]).abs() < 1e-12);
        // ARCTIC's own posing, written out by hand: lid corner (mm) turned about −Z by the
        // articulation, then the axis-angle and translation, then world2cam.
        let corner = Vector3::new(50.0, 40.0, 50.0) * 0.001;
        let (sa, ca) = (row[0].sin(), row[0].cos());
        let arti = nalgebra::Matrix3::new(ca, sa, 0.0, -sa, ca, 0.0, 0.0, 0.0, 1.0);
        let global = nalgebra::Rotation3::from_scaled_axis(Vector3::new(row[1], row[2], row[3]));
        let world = global * (arti * corner) + Vector3::new(row[4], row[5], row[6]) * 0.001;
        let cam = Vector3::new(world.x, -world.y, -world.z + 1.0);
        let top = gt.pose(&frame, "top").expect("top").to_rigid();
        let got = top * Point3::from(corner);
        assert!((got.coords - cam).norm() < 1e-9, "{frame}: {got} vs {cam}");
        // Intrinsics rescaled to the 64 × 48 images; the mask is where the object projects.
        let i = cap
            .frames
            .iter()
            .position(|f| f.name == frame)
            .expect("frame");
        let cam_i = &cap.frames[i].camera;
        assert!((cam_i.fx - 60.0).abs() < 1e-9 && (cam_i.cx - 32.0).abs() < 1e-9);
        let centre = top * Point3::new(0.0, 0.0, 0.03);
        let (u, v) = (
            60.0 * centre.x / centre.z + 32.0,
            60.0 * centre.y / centre.z + 24.0,
        );
        let (mx, my) = mask_centroid(&cap.load_mask(i).expect("mask"));
        assert!(
            (mx - u).abs() < 2.0 && (my - v).abs() < 2.0,
            "{mx},{my} vs {u},{v}"
        );
    }
    // A mislabelled template is named.
    std::fs::write(tpl.join("parts.json"), "[0, 1]").expect("w");
    let err = import_arctic(&cfg, &dir.path().join("cap2"))
        .expect_err("bad")
        .to_string();
    assert!(
        err.contains("parts.json") && err.contains("2 labels"),
        "{err}"
    );
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
        let p = problems_of(dir.path());
        assert!(
            p.contains("cameras.json") && p.contains("size"),
            "{size}: {p}"
        );
    }
    set(&|v| v["c2w"][1][3] = serde_json::json!([1.0, 2.0, 3.0, 4.0]));
    let p = problems_of(dir.path());
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
        let p = problems_of(dir.path());
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
        problems_of(dir.path())
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
