//! Integration tests of the renderer: exactness against an independent ray caster over many
//! poses, depth against ray-cast depth, and the silhouette/full renderers agreeing.

#[path = "../../agentstar-track/tests/common/hinged.rs"]
mod hinged;
mod support;

use agentstar_geom::pose::Similarity;
use agentstar_geom::primitives::{cone, cuboid, torus, uv_sphere};
use agentstar_geom::{
    KinematicTree, ObjectModel, Part, PinholeCamera, Point3, TriMesh, UnitQuaternion, Vector3,
};
use agentstar_render::{render_full, BitMask, PosedModel, SilhouetteRenderer};
use hinged::with_lid_hinge;
use support::assert_golden;

/// A deterministic generator for test poses.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E3779B97F4A7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58476D1CE4E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D049BB133111EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn range(&mut self, a: f64, b: f64) -> f64 {
        a + (b - a) * self.next()
    }
    fn rotation(&mut self) -> UnitQuaternion {
        let q = nalgebra::Quaternion::new(
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
            self.range(-1.0, 1.0),
        );
        UnitQuaternion::from_quaternion(q)
    }
    /// A pose that keeps a unit-sized model in view of the tests' 96×72 camera.
    fn pose_in_view(&mut self) -> Similarity {
        Similarity {
            scale: self.range(0.5, 1.5),
            rotation: self.rotation(),
            translation: Vector3::new(
                self.range(-0.3, 0.3),
                self.range(-0.2, 0.2),
                self.range(1.5, 3.0),
            ),
        }
    }
}

/// Möller–Trumbore from the camera centre, inclusive edges; nearest hit's planar depth.
fn ray_cast(meshes: &[TriMesh], camera: &PinholeCamera) -> (BitMask, Vec<f64>) {
    let mut mask = BitMask::new(camera.width, camera.height);
    let mut depth = vec![f64::INFINITY; (camera.width * camera.height) as usize];
    for y in 0..camera.height {
        for x in 0..camera.width {
            let d = camera.ray_direction(x as f64 + 0.5, y as f64 + 0.5);
            for mesh in meshes {
                for i in 0..mesh.triangles.len() {
                    let [a, b, c] = mesh.triangle(i);
                    let e1 = b - a;
                    let e2 = c - a;
                    let p = d.cross(&e2);
                    let det = e1.dot(&p);
                    if det.abs() < 1e-300 {
                        continue;
                    }
                    let inv = 1.0 / det;
                    let s = -a.coords;
                    let u = s.dot(&p) * inv;
                    if !(0.0..=1.0).contains(&u) {
                        continue;
                    }
                    let q = s.cross(&e1);
                    let v = d.dot(&q) * inv;
                    if v < 0.0 || u + v > 1.0 {
                        continue;
                    }
                    let t = e2.dot(&q) * inv;
                    if t > 1e-6 {
                        mask.set(x, y);
                        let k = (y * camera.width + x) as usize;
                        depth[k] = depth[k].min(t);
                    }
                }
            }
        }
    }
    (mask, depth)
}

fn test_model() -> ObjectModel {
    let body = cuboid(0.8, 0.5, 0.3).expect("box");
    let lid = cone(0.2, 0.05, 0.3, 24)
        .expect("cone")
        .translated(Vector3::new(0.0, 0.0, 0.3));
    let ring = torus(0.2, 0.05, 24, 8)
        .expect("torus")
        .translated(Vector3::new(0.5, 0.0, 0.0));
    let ball = uv_sphere(0.12, 16, 8)
        .expect("sphere")
        .translated(Vector3::new(-0.45, 0.1, 0.1));
    let parts = vec![
        Part::new("body", body, [0.8, 0.2, 0.2]),
        Part::new("lid", lid, [0.2, 0.8, 0.2]),
        Part::new("ring", ring, [0.2, 0.2, 0.8]),
        Part::new("ball", ball, [0.8, 0.8, 0.2]),
    ];
    with_lid_hinge(parts, Vector3::new(0.0, -0.2, 0.15), Vector3::x(), 120.0)
}

fn posed_meshes(model: &ObjectModel, states: &[f64], pose: &Similarity) -> Vec<TriMesh> {
    let transforms = model.tree.part_transforms(states);
    model
        .parts
        .iter()
        .zip(&transforms)
        .map(|(p, t)| {
            let full = pose.compose(&Similarity::from_rigid(t));
            TriMesh::new(
                p.mesh
                    .positions
                    .iter()
                    .map(|q| full.transform_point(q))
                    .collect(),
                p.mesh.triangles.clone(),
            )
        })
        .collect()
}

#[test]
fn silhouette_is_exact_against_ray_casting_over_many_poses() {
    let model = test_model();
    let camera = PinholeCamera::new(90.0, 90.0, 48.0, 36.0, 96, 72).expect("camera");
    let mut rng = Rng(7);
    let mut renderer = SilhouetteRenderer::new(96, 72);
    for trial in 0..60 {
        let pose = rng.pose_in_view();
        let states = [rng.range(0.0, 2.0)];
        let posed = PosedModel::new(&model, &states, &pose);
        let raster = renderer.render(&camera, &posed.instances).clone();
        let (exact, exact_depth) = ray_cast(&posed_meshes(&model, &states, &pose), &camera);
        assert!(exact.count() > 50, "trial {trial}: object not in view");
        let inter = raster.and(&exact).count();
        let union = raster.or(&exact).count();
        assert_eq!(
            inter,
            union,
            "trial {trial}: IoU {} ≠ 1",
            inter as f64 / union as f64
        );
        // Front faces found from their planes (only the contour's vertices projected) and
        // from every vertex projected give the same silhouette.
        assert!(posed.instances.iter().all(|i| i.planes.is_some()));
        let projected: Vec<_> = posed
            .instances
            .iter()
            .map(|i| agentstar_render::Instance { planes: None, ..*i })
            .collect();
        assert_eq!(
            renderer.render(&camera, &projected),
            &raster,
            "trial {trial}: the planes' and the projected faces' silhouettes differ"
        );
        // The full renderer covers the same pixels and its depth is the ray-cast depth.
        let full = render_full(&camera, &posed.instances);
        assert_eq!(
            full.silhouette(),
            raster,
            "trial {trial}: full and silhouette renderers differ"
        );
        for (k, &z) in full.depth.iter().enumerate() {
            if z.is_finite() {
                assert!(
                    (z as f64 - exact_depth[k]).abs() < 1e-4 * exact_depth[k],
                    "trial {trial}: depth {z} vs {}",
                    exact_depth[k]
                );
            }
        }
    }
}

/// Meshes that are not closed: a box with its top face missing, a sphere with a cap cut off,
/// two planes meeting in a T (an edge with three triangles), and a triangle soup of a cone
/// without its top (every triangle on its own vertices, as an STL file gives a mesh; a soup
/// of a closed surface is closed once its coincident vertices are shared, see
/// `Part::new`).
fn open_model() -> ObjectModel {
    let without = |mesh: TriMesh, keep: &dyn Fn(&[Point3; 3]) -> bool| {
        let triangles = (0..mesh.triangles.len())
            .filter(|&i| keep(&mesh.triangle(i)))
            .map(|i| mesh.triangles[i])
            .collect();
        TriMesh::new(mesh.positions, triangles).compacted()
    };
    let open_box = without(cuboid(0.8, 0.5, 0.3).expect("box"), &|t| {
        !t.iter().all(|p| (p.z - 0.15).abs() < 1e-9)
    });
    let cut_sphere = without(
        uv_sphere(0.2, 16, 8)
            .expect("sphere")
            .translated(Vector3::new(0.55, 0.0, 0.0)),
        &|t| t.iter().any(|p| p.z < 0.12),
    );
    let p = |x: f64, y: f64, z: f64| Point3::new(x, y, z);
    let tee = TriMesh::new(
        vec![
            p(-0.6, -0.3, 0.2),
            p(-0.2, -0.3, 0.2),
            p(-0.2, 0.3, 0.2),
            p(-0.6, 0.3, 0.2),
            p(-0.4, -0.3, 0.2),
            p(-0.4, 0.3, 0.2),
            p(-0.4, 0.3, 0.5),
            p(-0.4, -0.3, 0.5),
        ],
        vec![
            [0, 4, 5],
            [0, 5, 3],
            [4, 1, 2],
            [4, 2, 5],
            [4, 5, 6],
            [4, 6, 7],
        ],
    );
    let closed_cone = cone(0.15, 0.05, 0.3, 12)
        .expect("cone")
        .translated(Vector3::new(0.0, 0.4, -0.1));
    let top = closed_cone
        .positions
        .iter()
        .map(|p| p.z)
        .fold(f64::NEG_INFINITY, f64::max);
    let cone_mesh = without(closed_cone, &|t| {
        !t.iter().all(|p| (p.z - top).abs() < 1e-9)
    });
    let mut soup = TriMesh::default();
    for i in 0..cone_mesh.triangles.len() {
        let base = soup.positions.len() as u32;
        soup.positions.extend(cone_mesh.triangle(i));
        soup.triangles.push([base, base + 1, base + 2]);
    }
    let parts = vec![
        Part::new("open box", open_box, [0.8, 0.2, 0.2]),
        Part::new("cut sphere", cut_sphere, [0.2, 0.8, 0.2]),
        Part::new("tee", tee, [0.2, 0.2, 0.8]),
        Part::new("soup", soup, [0.8, 0.8, 0.2]),
    ];
    let names: Vec<String> = parts.iter().map(|p| p.name.clone()).collect();
    ObjectModel {
        tree: KinematicTree::new(vec![], &names).expect("tree"),
        parts,
    }
}

#[test]
fn open_meshes_are_exact_against_ray_casting_and_the_per_triangle_path() {
    let model = open_model();
    assert!(model
        .parts
        .iter()
        .all(|p| !p.watertight && p.open_edges.is_some()));
    let camera = PinholeCamera::new(90.0, 90.0, 48.0, 36.0, 96, 72).expect("camera");
    let mut rng = Rng(11);
    let mut renderer = SilhouetteRenderer::new(96, 72);
    for trial in 0..60 {
        let pose = rng.pose_in_view();
        let posed = PosedModel::new(&model, &[], &pose);
        let raster = renderer.render(&camera, &posed.instances).clone();
        let (exact, _) = ray_cast(&posed_meshes(&model, &[], &pose), &camera);
        assert!(exact.count() > 50, "trial {trial}: object not in view");
        assert_eq!(
            raster.and(&exact).count(),
            raster.or(&exact).count(),
            "trial {trial}: not the ray-cast silhouette"
        );
        // Triangle by triangle, as open meshes were filled before.
        let by_triangle: Vec<_> = posed
            .instances
            .iter()
            .map(|i| agentstar_render::Instance {
                open_edges: None,
                planes: None,
                ..*i
            })
            .collect();
        assert_eq!(
            renderer.render(&camera, &by_triangle),
            &raster,
            "trial {trial}"
        );
        assert_eq!(render_full(&camera, &posed.instances).silhouette(), raster);
    }
}

#[test]
fn geometry_crossing_the_near_plane_is_clipped_not_dropped() {
    // A large plane through the camera: half of it is behind the camera.
    let mesh = agentstar_geom::primitives::cuboid(4.0, 4.0, 0.01).expect("box");
    let part = Part::new("slab", mesh, [1.0; 3]);
    let model = ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![part],
    };
    let pose = Similarity {
        scale: 1.0,
        rotation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.3),
        translation: Vector3::new(0.0, 0.05, 0.5),
    };
    let camera = PinholeCamera::new(40.0, 40.0, 24.0, 16.0, 48, 32).expect("camera");
    let posed = PosedModel::new(&model, &[], &pose);
    let mut r = SilhouetteRenderer::new(48, 32);
    let raster = r.render(&camera, &posed.instances).clone();
    let (exact, _) = ray_cast(&posed_meshes(&model, &[], &pose), &camera);
    assert!(exact.count() > 200, "{}", exact.count());
    assert_eq!(raster, exact);
}

/// The stretches of `render_spans` cover exactly the pixels whose centres the mask holds:
/// over a closed model (the contour fill), an open one, and geometry crossing the near
/// plane (the per-triangle fill).
#[test]
fn render_spans_cover_exactly_the_masks_pixel_centres() {
    let check = |cam: &PinholeCamera, model: &ObjectModel, states: &[f64], pose: &Similarity| {
        let mut r = SilhouetteRenderer::new(cam.width, cam.height);
        let posed = PosedModel::new(model, states, pose);
        let mask = r.render(cam, &posed.instances).clone();
        let spans = r.render_spans(cam, &posed.instances).to_vec();
        assert!(!spans.is_empty());
        let covered = BitMask::from_fn(cam.width, cam.height, |x, y| {
            let c = x as f64 + 0.5;
            spans.iter().any(|s| s.row == y && s.x0 <= c && c <= s.x1)
        });
        assert_eq!(covered, mask);
        // Recording the stretches leaves the mask as a plain render draws it.
        assert_eq!(r.mask(), &mask);
    };
    let cam = PinholeCamera::new(300.0, 300.0, 160.0, 120.0, 320, 240).expect("camera");
    let mut rng = Rng(7);
    let model = test_model();
    for _ in 0..6 {
        let mut pose = rng.pose_in_view();
        pose.translation *= 2.0;
        check(&cam, &model, &[0.4], &pose);
    }
    let open = open_model();
    for _ in 0..3 {
        let mut pose = rng.pose_in_view();
        pose.translation *= 2.0;
        check(&cam, &open, &[], &pose);
    }
    let slab = ObjectModel {
        tree: KinematicTree::rigid(1),
        parts: vec![Part::new(
            "slab",
            cuboid(4.0, 4.0, 0.01).expect("box"),
            [1.0; 3],
        )],
    };
    let through = Similarity {
        scale: 1.0,
        rotation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 1.3),
        translation: Vector3::new(0.0, 0.05, 0.5),
    };
    let small = PinholeCamera::new(40.0, 40.0, 24.0, 16.0, 48, 32).expect("camera");
    check(&small, &slab, &[], &through);
}

#[test]
fn renderer_reuse_clears_previous_frames() {
    let model = test_model();
    let camera = PinholeCamera::new(90.0, 90.0, 48.0, 36.0, 96, 72).expect("camera");
    let mut r = SilhouetteRenderer::new(96, 72);
    let near = Similarity {
        scale: 1.0,
        rotation: UnitQuaternion::identity(),
        translation: Vector3::new(0.0, 0.0, 1.5),
    };
    let far = Similarity {
        translation: Vector3::new(0.2, 0.0, 6.0),
        ..near
    };
    let a = r
        .render(&camera, &PosedModel::new(&model, &[0.0], &near).instances)
        .count();
    let b = r
        .render(&camera, &PosedModel::new(&model, &[0.0], &far).instances)
        .clone();
    let mut fresh = SilhouetteRenderer::new(96, 72);
    let c = fresh
        .render(&camera, &PosedModel::new(&model, &[0.0], &far).instances)
        .clone();
    assert!(a > b.count());
    assert_eq!(b, c);
    let _ = Point3::origin();
    // The reported rows hold every pixel of the last render, and the row-restricted gate
    // equals the full one; an empty render reports none.
    let (y0, y1) = r.rows().expect("rows");
    for y in 0..72 {
        for x in 0..96 {
            assert!(!b.get(x, y) || (y0..=y1).contains(&y), "({x}, {y})");
        }
    }
    let target = agentstar_render::ScoreTarget::new(c.clone(), None).expect("target");
    assert_eq!(target.gate_rows(r.mask(), r.rows()), target.gate(&b));
    let behind = Similarity {
        translation: Vector3::new(0.0, 0.0, -6.0),
        ..near
    };
    r.render(&camera, &PosedModel::new(&model, &[0.0], &behind).instances);
    assert_eq!(r.rows(), None);
    assert_eq!(r.mask().count(), 0);
}

#[test]
fn a_reused_full_renderer_gives_what_a_fresh_one_gives() {
    let model = test_model();
    let camera = PinholeCamera::new(90.0, 90.0, 48.0, 36.0, 96, 72).expect("camera");
    let mut rng = Rng(11);
    let mut reused = agentstar_render::FullRenderer::default();
    // Near and far poses in turn: a large render, then a small one in other rows.
    for trial in 0..12 {
        let mut pose = rng.pose_in_view();
        if trial % 2 == 1 {
            pose.translation.z *= 3.0;
            pose.translation.y += 0.3;
        }
        let states = [rng.range(0.0, 2.0)];
        let posed = PosedModel::new(&model, &states, &pose);
        let fresh = render_full(&camera, &posed.instances);
        let again = reused.render(&camera, &posed.instances);
        assert!(fresh.part.iter().any(|&p| p != agentstar_render::NO_PART));
        assert_eq!(again.part, fresh.part, "trial {trial}");
        assert_eq!(again.depth, fresh.depth, "trial {trial}");
        assert_eq!(again.normal, fresh.normal, "trial {trial}");
    }
}

#[test]
fn shaded_part_id_and_comparison_views_match_their_goldens() {
    use agentstar_render::views::{
        flatten, part_id_view, shade, silhouette_comparison, ShadeOptions,
    };
    let model = test_model();
    let camera = PinholeCamera::new(60.0, 60.0, 32.0, 32.0, 64, 64).expect("camera");
    let pose = Similarity {
        scale: 1.0,
        rotation: UnitQuaternion::from_axis_angle(&Vector3::x_axis(), 2.0)
            * UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.5),
        translation: Vector3::new(0.0, 0.0, 2.2),
    };
    let posed = PosedModel::new(&model, &[0.8], &pose);
    let buffers = render_full(&camera, &posed.instances);
    let colors: Vec<[f32; 3]> = model.parts.iter().map(|p| p.color).collect();
    assert_golden(
        "shaded.png",
        &flatten(
            &shade(&buffers, &colors, ShadeOptions::default()),
            image::Rgb([0, 0, 0]),
        ),
    );
    let (ids, vis) = part_id_view(&buffers, &model.part_names());
    assert!(vis.iter().all(|v| v.pixels > 0), "{vis:?}");
    assert_golden("ids.png", &ids);
    let shifted = Similarity {
        translation: Vector3::new(0.05, 0.0, 2.2),
        ..pose
    };
    let mut r = SilhouetteRenderer::new(64, 64);
    let other = r
        .render(
            &camera,
            &PosedModel::new(&model, &[0.8], &shifted).instances,
        )
        .clone();
    let hand = BitMask::from_fn(64, 64, |x, y| x > 44 && y > 40);
    let (cmp, counts) = silhouette_comparison(&buffers.silhouette(), &other, Some(&hand));
    assert!(counts.render_only > 0 && counts.mask_only > 0 && counts.both > counts.render_only);
    assert_golden("compare.png", &cmp);
}
