//! The datasets' files as the importer tests write them (a BOP scene, a HOT3D sequence, an
//! ARCTIC sequence), shared by `agentstar-import`'s tests and the binary's in-between tests.

use agentstar_data::export::glb_bytes;
use agentstar_data::scenefile::load_scene_script;
use agentstar_geom::nalgebra;
use agentstar_geom::{UnitQuaternion, Vector3};
use image::{GrayImage, Luma, RgbImage};
use std::path::Path;

/// Writes a small BOP scene: a 60 × 40 × 30 mm box (object 3) and a second object
/// (object 7) partly in front of it, seen by a moving camera in the images `ids` (the box
/// turns by about 13° and the camera moves 10 mm from one id to the next), with masks,
/// 16-bit depth and models_info symmetries.
pub fn write_bop_scene(
    root: &Path,
    ids: &[u32],
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
    for &id in ids {
        let k = id as f64;
        let pose = ObjectPose::new(
            UnitQuaternion::from_euler_angles(0.4 + 0.1 * k, -0.3, 0.2 * k),
            Vector3::new(0.005 * k, -0.004, 0.4),
        );
        let other = ObjectPose::new(UnitQuaternion::identity(), Vector3::new(0.02, 0.01, 0.3));
        let inst = |m: &'static agentstar_geom::TriMesh, p: &ObjectPose, id: u16| {
            Instance::bare(m, Affine::from_similarity(&p.with_scale(1.0)), id)
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

pub fn rigid(axis: [f64; 3], angle_deg: f64, t: [f64; 3]) -> agentstar_geom::pose::Rigid {
    agentstar_geom::pose::Rigid::from_parts(
        Vector3::new(t[0], t[1], t[2]).into(),
        UnitQuaternion::from_axis_angle(
            &nalgebra::Unit::new_normalize(Vector3::new(axis[0], axis[1], axis[2])),
            angle_deg.to_radians(),
        ),
    )
}

pub fn csv_row(uid: &str, t: u64, p: &agentstar_geom::pose::Rigid) -> String {
    let q = p.rotation;
    let v = p.translation.vector;
    // Columns in an order other than the documented one: found by name.
    format!(
        "{},{},{},{},{},{},{},{},{}\n",
        t, uid, q.w, q.i, q.j, q.k, v.x, v.y, v.z
    )
}

/// Writes a HOT3D sequence under `root`: a 12 × 6 × 4 cm box (object `1234`, beside object
/// `999`) turning 20° a frame in `frames` frames 33 ms apart, a headset moving with poses 2 ms
/// off the frame times, and one more frame with no pose near it. Returns the import of the
/// box (masks rendered, every frame a keyframe) and each frame's time stamp with the true
/// `camera_from_object`.
pub fn hot3d_sequence(
    root: &Path,
    frames: u64,
) -> (
    agentstar_import::hot3d::Hot3dImport,
    Vec<(u64, agentstar_geom::pose::Rigid)>,
) {
    use agentstar_import::hot3d::Hot3dImport;
    let seq = root.join("seq");
    let models = root.join("object_models");
    let frames_dir = root.join("frames");
    for d in [&seq, &models, &frames_dir] {
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
    for k in 0..frames {
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
            .save(frames_dir.join(format!("{t}.png")))
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
        .save(frames_dir.join("5000000000.png"))
        .expect("frame");
    let cfg = Hot3dImport {
        sequence: seq.clone(),
        models: models.clone(),
        object_uid: "1234".into(),
        frames: frames_dir.clone(),
        masks: None,
        hands: None,
        intrinsics: [60.0, 60.0, 32.0, 24.0],
        device_from_camera,
        max_dt_ns: 5_000_000,
        every: 1,
        between: None,
    };
    (cfg, truth)
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

/// Writes an ARCTIC data root under `dir/arctic`: a two-part box template (a 100 × 80 × 40 mm
/// bottom and a 10 mm lid above it), subject `s01`'s cameras (camera 3 seen at 64 × 48), and
/// sequence `box_grab_01` of `n_rows` object rows (the lid opening 0.3 rad a row) with images
/// numbered from 00001 (offset 2: 00001 falls before the array). Returns the import of
/// camera 3 (masks rendered, every image a keyframe), the rows, the lid's mesh (millimetres)
/// and the template folder.
pub fn arctic_sequence(
    dir: &Path,
    n_rows: usize,
) -> (
    agentstar_import::arctic::ArcticImport,
    Vec<[f64; 7]>,
    agentstar_geom::TriMesh,
    std::path::PathBuf,
) {
    use agentstar_import::arctic::ArcticImport;
    let root = dir.join("arctic");
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
    let rows: Vec<[f64; 7]> = (0..n_rows)
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
    // Images 00002.. hold rows 0.. (offset 2); 00001 falls before the array.
    for n in 1..=n_rows + 1 {
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
        between: None,
    };
    (cfg, rows, lid, tpl)
}
