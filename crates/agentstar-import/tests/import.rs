//! The dataset importers against files written by the tests: a BOP scene, frame folders
//! with COLMAP (binary and text) and nerfstudio cameras, a HOT3D sequence and an ARCTIC
//! sequence, each compared with the dataset's own formulas written out independently.

mod datasets;

use agentstar_data::capture::Capture;
use agentstar_geom::nalgebra;
use agentstar_geom::{Point3, UnitQuaternion, Vector3};
use datasets::{arctic_sequence, hot3d_sequence, write_bop_scene};
use image::{GrayImage, Luma, RgbImage};

#[test]
fn a_bop_scene_imports_with_metres_occluders_depth_and_ground_truth() {
    use agentstar_data::gt::GroundTruth;
    use agentstar_import::bop::{import_bop, BopImport};
    let dir = tempfile::tempdir().expect("tmp");
    let (poses, cam) = write_bop_scene(dir.path(), &[0, 2, 4]);
    let out = dir.path().join("cap");
    let cfg = BopImport {
        scene: dir.path().join("scene"),
        models: dir.path().join("models"),
        obj_id: 3,
        every: 1,
        between: None,
        depth: true,
    };
    assert_eq!(import_bop(&cfg, &out).expect("import").keyframes, 3);
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
    let inst = agentstar_render::Instance::bare(
        &gt.meshes["object"],
        agentstar_render::raster::Affine::from_similarity(&p.with_scale(1.0)),
        0,
    );
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

/// The capture an importer wrote at `out`, asserting that it validates, and its ground truth.
fn imported(out: &std::path::Path) -> (Capture, agentstar_data::gt::GroundTruth) {
    let problems = Capture::validate(out);
    assert!(problems.is_empty(), "{}: {problems:?}", out.display());
    let cap = Capture::open(out).expect("capture");
    let gt = agentstar_data::gt::GroundTruth::load(&out.join("gt.json")).expect("gt");
    (cap, gt)
}

#[test]
fn a_hot3d_sequence_imports_with_headset_cameras_and_nearest_poses() {
    use agentstar_import::hot3d::import_hot3d;
    let dir = tempfile::tempdir().expect("tmp");
    let root = dir.path();
    let (cfg, truth) = hot3d_sequence(root, 4);
    let seq = root.join("seq");
    let out = root.join("cap");
    let summary = import_hot3d(&cfg, &out).expect("import");
    assert_eq!(
        (summary.frames, summary.skipped, summary.rendered_masks),
        (4, 1, true)
    );
    let (cap, gt) = imported(&out);
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

#[test]
fn an_arctic_sequence_imports_two_parts_and_the_articulation() {
    use agentstar_import::arctic::import_arctic;
    let dir = tempfile::tempdir().expect("tmp");
    let (cfg, rows, lid, tpl) = arctic_sequence(dir.path(), 6);
    let out = dir.path().join("cap");
    assert_eq!(import_arctic(&cfg, &out).expect("import").keyframes, 6);
    let (cap, gt) = imported(&out);
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

/// The names of the keyframes and of the in-between frames of a capture.
fn frame_names(cap: &Capture) -> (Vec<String>, Vec<String>) {
    (
        cap.frames.iter().map(|f| f.name.clone()).collect(),
        cap.between.iter().map(|f| f.name.clone()).collect(),
    )
}

fn names(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

/// Every in-between frame of `cap` has a camera and a mask showing the object where the
/// ground truth puts it (the masks read or rendered as the keyframes' are).
fn assert_in_between_frames_complete(cap: &Capture) {
    for f in &cap.between {
        let mask = cap.load_mask_of(f).expect("in-between mask");
        assert!(mask.count() > 0, "{}: empty mask", f.name);
        assert!(f.camera.fx > 0.0, "{}: camera", f.name);
    }
}

#[test]
fn dataset_imports_keep_in_between_frames_on_request() {
    use agentstar_data::gt::GroundTruth;
    use agentstar_import::arctic::import_arctic;
    use agentstar_import::bop::{import_bop, BopImport};
    use agentstar_import::hot3d::import_hot3d;
    let dir = tempfile::tempdir().expect("tmp");
    let root = dir.path();
    // BOP: images 0..6; keyframes every 3rd, the images between them too (every one, then
    // every 2nd).
    write_bop_scene(&root.join("bop"), &[0, 1, 2, 3, 4, 5, 6]);
    let bop = BopImport {
        scene: root.join("bop/scene"),
        models: root.join("bop/models"),
        obj_id: 3,
        every: 3,
        between: Some(1),
        depth: true,
    };
    let written = import_bop(&bop, &root.join("bop1")).expect("import");
    assert_eq!((written.keyframes, written.between), (3, 4));
    assert!(Capture::validate(&root.join("bop1")).is_empty());
    let cap = Capture::open(&root.join("bop1")).expect("capture");
    assert_eq!(
        frame_names(&cap),
        (
            names(&["000000.png", "000003.png", "000006.png"]),
            names(&["000001.png", "000002.png", "000004.png", "000005.png"])
        )
    );
    assert_in_between_frames_complete(&cap);
    // In-between frames keep the occluders' masks and depth as keyframes do.
    let f = &cap.between[0];
    assert!(
        cap.load_hand_of(f)
            .expect("read")
            .expect("occluder")
            .count()
            > 0
    );
    assert!(cap.load_depth_of(f).expect("read").is_some());
    // Their cameras move with the source's: image 1's camera sits 10 mm along +X.
    assert!((f.world_from_camera.translation.vector.x - 0.01).abs() < 1e-9);
    // gt.json holds the keyframes only.
    let gt = GroundTruth::load(&root.join("bop1/gt.json")).expect("gt");
    assert_eq!(
        gt.file.frames.keys().cloned().collect::<Vec<_>>(),
        names(&["000000.png", "000003.png", "000006.png"])
    );
    let written = import_bop(
        &BopImport {
            between: Some(2),
            ..bop.clone()
        },
        &root.join("bop2"),
    )
    .expect("import");
    assert_eq!((written.keyframes, written.between), (3, 2));
    let cap = Capture::open(&root.join("bop2")).expect("capture");
    assert_eq!(cap.between.len(), 2);
    assert_eq!(
        (cap.between[0].name.as_str(), cap.between[1].name.as_str()),
        ("000002.png", "000005.png")
    );
    // Without --between the import is as before: no `keyframes` key.
    import_bop(
        &BopImport {
            between: None,
            ..bop.clone()
        },
        &root.join("bop0"),
    )
    .expect("import");
    let manifest = std::fs::read_to_string(root.join("bop0/capture.json")).expect("read");
    assert!(!manifest.contains("\"keyframes\""), "{manifest}");
    // A stride of 0, or one that reaches the next keyframe, is refused; nothing is written.
    for (every, between, says) in [
        (3, 0, "--between 0"),
        (3, 3, "from 1 to 2"),
        (1, 1, "every frame is a keyframe"),
    ] {
        let out = root.join(format!("bad-{every}-{between}"));
        let e = import_bop(
            &BopImport {
                every,
                between: Some(between),
                ..bop.clone()
            },
            &out,
        )
        .expect_err("refused")
        .to_string();
        assert!(e.contains(says), "{e}");
        assert!(!out.exists());
    }
    // HOT3D: 7 frames, keyframes every 3rd, masks rendered for every frame kept.
    let (mut hot3d, truth) = hot3d_sequence(&root.join("hot3d"), 7);
    hot3d.every = 3;
    hot3d.between = Some(1);
    let summary = import_hot3d(&hot3d, &root.join("hot3d1")).expect("import");
    assert_eq!(
        (summary.frames, summary.between, summary.skipped),
        (3, 4, 0)
    );
    assert!(Capture::validate(&root.join("hot3d1")).is_empty());
    let cap = Capture::open(&root.join("hot3d1")).expect("capture");
    let stamp = |k: usize| format!("{}.png", truth[k].0);
    let (key, between) = frame_names(&cap);
    assert_eq!(key, vec![stamp(0), stamp(3), stamp(6)]);
    assert_eq!(between, vec![stamp(1), stamp(2), stamp(4), stamp(5)]);
    assert_in_between_frames_complete(&cap);
    let gt = GroundTruth::load(&root.join("hot3d1/gt.json")).expect("gt");
    assert_eq!(gt.file.frames.len(), 3);
    assert!(gt.file.frames.contains_key(&stamp(3)) && !gt.file.frames.contains_key(&stamp(4)));
    // ARCTIC: 8 rows; keyframes every 3rd image (at most 2), the images between them: the
    // articulation's states are the keyframes' only.
    let (mut arctic, _, _, _) = arctic_sequence(&root.join("arctic"), 8);
    arctic.every = 3;
    arctic.max_frames = Some(2);
    arctic.between = Some(1);
    let written = import_arctic(&arctic, &root.join("arctic1")).expect("import");
    assert_eq!((written.keyframes, written.between), (2, 2));
    assert!(Capture::validate(&root.join("arctic1")).is_empty());
    let cap = Capture::open(&root.join("arctic1")).expect("capture");
    assert_eq!(
        frame_names(&cap),
        (
            names(&["00002.png", "00005.png"]),
            names(&["00003.png", "00004.png"])
        )
    );
    assert_in_between_frames_complete(&cap);
    let gt = GroundTruth::load(&root.join("arctic1/gt.json")).expect("gt");
    assert_eq!(
        gt.file.joints[0].states.keys().cloned().collect::<Vec<_>>(),
        names(&["00002.png", "00005.png"])
    );
    // An in-between image without its mask in a given mask folder is named.
    let masks = root.join("arctic-masks");
    std::fs::create_dir_all(&masks).expect("mkdir");
    for n in [2, 3, 5] {
        image::GrayImage::from_pixel(64, 48, image::Luma([255]))
            .save(masks.join(format!("{n:05}.png")))
            .expect("mask");
    }
    arctic.masks = Some(masks);
    let e = import_arctic(&arctic, &root.join("arctic2"))
        .expect_err("mask missing")
        .to_string();
    assert!(e.contains("in-between image `00004`"), "{e}");
    assert!(!root.join("arctic2").exists());
}
