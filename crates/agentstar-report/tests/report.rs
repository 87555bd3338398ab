//! The page from a hand-made report: every section, the viewer's data as it will be decoded,
//! escaping, and nothing fetched from elsewhere.

mod browser;

use agentstar_report::{
    render_html, FrameEntry, Image, Report, Step, Temporal, Viewer, ViewerFrame, ViewerMaterial,
    ViewerPart, ViewerSurface, ViewerTexture,
};
use browser::{chromium, view_pixels, viewer_dom};

fn identity() -> [f64; 16] {
    let mut m = [0.0; 16];
    for i in 0..4 {
        m[i * 5] = 1.0;
    }
    m
}

fn report() -> Report {
    let png = Image {
        mime: "image/png".into(),
        bytes: vec![0x89, b'P', b'N', b'G'],
    };
    let frame = |name: &str, iou: Option<f64>| FrameEntry {
        name: name.into(),
        frame: png.clone(),
        overlay: png.clone(),
        iou_visible: iou,
        iou_raw: 0.9,
        facing: Some(format!("+Z toward the camera <{name}>")),
    };
    Report {
        title: "run <1>".into(),
        facts: vec![("parts".into(), "body, lid".into())],
        metrics: vec![("EPE".into(), "0.48 cm".into())],
        gate: 0.98,
        frames: vec![frame("000000.png", Some(0.99)), frame("000005.png", None)],
        viewer: Viewer {
            parts: vec![ViewerPart {
                name: "body".into(),
                color: [0.8, 0.3, 0.2],
                positions: vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0],
                triangles: vec![0, 1, 2],
                surface: None,
            }],
            joint_names: vec!["hinge".into()],
            frames: ["000000.png", "000005.png"]
                .iter()
                .map(|n| ViewerFrame {
                    name: n.to_string(),
                    world_from_part: vec![identity()],
                    world_from_camera: identity(),
                    intrinsics: [100.0, 100.0, 50.0, 40.0],
                    size: [100, 80],
                    joint_states: vec![12.5],
                })
                .collect(),
        },
        temporal: Some(Temporal {
            pose_frame: "oriented".into(),
            frames: vec!["000005.png".into()],
            rot_step_deg: vec![Some(20.0)],
            trans_step: vec![Some(0.1)],
            warnings: vec![],
        }),
        steps: vec![Step {
            step: 1,
            time_s: 0.5,
            kind: "pose".into(),
            tool: "sweep".into(),
            summary: "picked candidate 2 </script>".into(),
            scores: vec![("iou".into(), 0.97)],
            images: vec![
                ("sweep.png".into(), Some(png.clone())),
                ("gone.png".into(), None),
            ],
        }],
        notes: vec!["ledger line 3 skipped".into()],
        generator: "agentstar test".into(),
    }
}

#[test]
fn the_page_holds_every_section_and_decodable_viewer_data() {
    let html = render_html(&report());
    for id in ["summary", "viewer", "plots", "frames", "timeline"] {
        assert!(
            html.contains(&format!("<section id=\"{id}\"")),
            "no section {id}"
        );
    }
    assert!(html.contains("<title>run &lt;1&gt;</title>"));
    assert!(html.contains("picked candidate 2 &lt;/script&gt;"));
    assert!(html.contains("gone.png (missing)"));
    assert!(html.contains("ledger line 3 skipped"));
    // Two keyframes, the second without a visible mask and marked below the gate.
    assert_eq!(html.matches("<figure id=\"frame-").count(), 2);
    assert!(html.contains("no visible mask"));
    // Each keyframe names the side toward the camera, escaped.
    assert!(html.contains(r#"<span class="facing">+Z toward the camera &lt;000005.png&gt;</span>"#));
    // The viewer's data parse back, with the mesh as little-endian f32/u32 in base64.
    let start = html
        .find("<script id=\"report-data\" type=\"application/json\">")
        .expect("data")
        + "<script id=\"report-data\" type=\"application/json\">".len();
    let end = start + html[start..].find("</script>").expect("end");
    let data: serde_json::Value = serde_json::from_str(&html[start..end]).expect("json");
    assert_eq!(data["frames"].as_array().expect("frames").len(), 2);
    assert_eq!(data["joint_names"][0], "hinge");
    use base64::Engine;
    let bytes = base64::engine::general_purpose::STANDARD
        .decode(data["parts"][0]["positions"].as_str().expect("positions"))
        .expect("base64");
    let floats: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
        .collect();
    assert_eq!(floats, vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]);
    // Offline: three.js is inline, nothing is fetched.
    assert!(html.contains("<script id=\"three-src\" type=\"text/plain\">"));
    assert!(!html.contains("src=\"http") && !html.contains("<link"));
    // The plots: IoU with the gate, rotation and translation steps, joint states.
    assert_eq!(html.matches("<svg class=\"chart\"").count(), 4);
    assert!(html.contains("gate 0.98"));
}

fn png_bytes(img: &image::RgbImage) -> Vec<u8> {
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .expect("png");
    out
}

/// A textured, vertex-coloured part in the 3-D view (issue 33): the page carries its
/// texture and corner colours, and in a browser the view starts and draws it without a
/// script error.
#[test]
fn a_textured_part_is_drawn_by_the_viewer() {
    let mut r = report();
    let frame_png = Image {
        mime: "image/png".into(),
        bytes: png_bytes(&image::RgbImage::from_pixel(
            100,
            80,
            image::Rgb([90, 90, 90]),
        )),
    };
    for f in &mut r.frames {
        f.frame = frame_png.clone();
        f.overlay = frame_png.clone();
    }
    let print = image::RgbImage::from_fn(2, 2, |x, y| {
        image::Rgb([200 * (x as u8), 200 * (y as u8), 90])
    });
    // A square 0.6 wide, 2 in front of the camera: one triangle textured, one plain.
    r.viewer.parts = vec![ViewerPart {
        name: "label".into(),
        color: [0.8, 0.3, 0.2],
        positions: vec![
            -0.3, -0.3, 2.0, 0.3, -0.3, 2.0, 0.3, 0.3, 2.0, -0.3, 0.3, 2.0,
        ],
        triangles: vec![0, 1, 2, 0, 2, 3],
        surface: Some(ViewerSurface {
            order: vec![0, 1],
            corner_colors: vec![
                1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 1.0, 0.5, 0.5, 0.5, 1.0, 0.5, 1.0,
                1.0, 1.0,
            ],
            corner_uvs: vec![0.0, 0.0, 1.0, 0.0, 1.0, 1.0, 0.0, 0.0, 1.0, 1.0, 0.0, 1.0],
            groups: vec![(1, 0), (1, 1)],
            materials: vec![
                ViewerMaterial {
                    color: [1.0, 1.0, 1.0],
                    texture: Some(0),
                },
                ViewerMaterial {
                    color: [0.2, 0.6, 0.9],
                    texture: None,
                },
            ],
            textures: vec![ViewerTexture {
                png: png_bytes(&print),
                wrap: [33071, 10497],
            }],
        }),
    }];
    let html = render_html(&r);
    assert!(
        html.contains("\"surface\""),
        "the part's surface is in the page"
    );
    assert!(html.contains("data:image/png;base64,"));
    let Some(bin) = chromium() else { return };
    let dir = tempfile::tempdir().expect("tmp");
    let page = dir.path().join("report.html");
    std::fs::write(&page, &html).expect("page");
    let dom = viewer_dom(&bin, &page);
    let px = view_pixels(&dom, "data-cam-pixels");
    assert!(px > 200, "the camera view shows {px} pixels of the part");
}
