//! The dataset importers against files written by the tests: a BOP scene, frame folders
//! with COLMAP (binary and text) and nerfstudio cameras, a HOT3D sequence and an ARCTIC
//! sequence, each compared with the dataset's own formulas written out independently.

use agentstar_data::capture::Capture;
use agentstar_data::export::glb_bytes;
use agentstar_data::scenefile::load_scene_script;
use agentstar_geom::nalgebra;
use agentstar_geom::{Point3, UnitQuaternion, Vector3};
use image::{GrayImage, Luma, RgbImage};
use std::path::Path;

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
        r#"{"3": {"diameter": 78.1, "symmetries_discrete": [[-1, 0, 0, 0, 0, -1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]], "symmetries_continuous": [{"axis": [0, 1, 0], "offset": [0, 0, 0]}]}}"#,
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
            open_edges: None,
            planes: None,
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
    use agentstar_data::gt::GroundTruth;
    use agentstar_import::bop::{import_bop, BopImport};
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
    // The discrete half turn, then the continuous turn about Y as BOP discretises it
    // (⌈π / 0.01⌉ = 315 turns, identity left out), then each turn after the half turn.
    assert_eq!(gt.file.symmetries.len(), 1 + 314 + 314);
    let last = gt.file.symmetries[1 + 314 + 313];
    let q = |w: [f64; 4]| {
        agentstar_geom::UnitQuaternion::from_quaternion(agentstar_geom::nalgebra::Quaternion::new(
            w[0], w[1], w[2], w[3],
        ))
    };
    let expected = q(gt.file.symmetries[1 + 313]) * q(gt.file.symmetries[0]);
    assert!(q(last).angle_to(&expected) < 1e-9);
    assert!(
        gt.file.symmetries[0][3].abs() > 0.999,
        "a half turn about Z"
    );
    let first = gt.file.symmetries[1];
    let half = (std::f64::consts::PI / 315.0).sin();
    assert!((first[2] - half).abs() < 1e-9 && first[1].abs() < 1e-12 && first[3].abs() < 1e-12);
    // Rendering the ground truth gives back the visible mask outside the occluder.
    let inst = agentstar_render::Instance {
        mesh: &gt.meshes["object"],
        bounds: gt.meshes["object"].bounds(),
        camera_from_mesh: agentstar_render::raster::Affine::from_similarity(&p.with_scale(1.0)),
        edges: None,
        open_edges: None,
        planes: None,
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
    use agentstar_geom::pose::Rigid;
    use agentstar_import::video::{import_video, CameraSource, VideoImport};
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
                between: None,
            },
            &out,
        )
        .unwrap_or_else(|e| panic!("{label}: {e}"));
        assert_eq!(n.frames, 3);
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
        between: None,
    };
    assert_eq!(import_video(&cfg, &out).expect("fov").frames, 2);
    // The frame between the two keyframes kept as an in-between frame (formats.md §2).
    let with_between = VideoImport {
        between: Some(1),
        ..cfg.clone()
    };
    let out_between = dir.path().join("cap_between");
    assert_eq!(
        import_video(&with_between, &out_between)
            .expect("between")
            .frames,
        3
    );
    let cap = Capture::open(&out_between).expect("valid");
    assert_eq!(cap.frames.len(), 2, "keyframes");
    assert_eq!(cap.between.len(), 1, "in-between frames");
    assert_eq!(cap.between_keyframes(0).len(), 1);
    assert!(Capture::validate(&out_between).is_empty());
    // Its mask is required like a keyframe's, and named when missing.
    let spare = dir.path().join("img_1_mask.png");
    std::fs::rename(masks.join("img_1_mask.png"), &spare).expect("mv");
    let e = import_video(&with_between, &dir.path().join("y")).expect_err("no mask");
    assert!(
        e.to_string().contains("in-between") && e.to_string().contains("img_1"),
        "{e}"
    );
    assert!(!dir.path().join("y").exists(), "nothing written");
    std::fs::rename(&spare, masks.join("img_1_mask.png")).expect("mv back");
    std::fs::remove_file(masks.join("img_2_mask.png")).expect("rm");
    let e = import_video(&cfg, &dir.path().join("x")).expect_err("missing mask");
    assert!(e.to_string().contains("img_2"), "{e}");
    let bytes = std::fs::read(colmap_bin.join("images.bin")).expect("read");
    std::fs::write(colmap_bin.join("images.bin"), &bytes[..bytes.len() - 30]).expect("truncate");
    let e = agentstar_import::cameras::read_colmap(&colmap_bin).expect_err("truncated");
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
    use agentstar_import::hot3d::{import_hot3d, Hot3dImport};
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
    use agentstar_import::arctic::{import_arctic, ArcticImport};
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
