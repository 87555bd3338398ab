//! A seeded mutation fuzzer over every parser a user or a model reaches through files: scene
//! scripts, `capture.json`, `keyframes.json`, `cameras.json`, `.npy`/`.npz`, PNG and JPEG
//! frames, `pose.json`, `gt.json`, URDF and the mesh formats (the model-server replies are
//! fuzzed the same way in `agentstar-agent/tests/fuzz_replies.rs`).
//!
//! Each target starts from the committed corpus in `fuzz/corpus/<target>/` and mutates it
//! (bit flips, interesting bytes and tokens such as `NaN`, `1e300`, `-1`, deletions,
//! duplications, truncations and splices between seeds) with a seeded generator, so a run
//! is reproducible from its seed. A case fails when the parser panics or takes longer than
//! `harness::SLOW` (10 s); failing inputs are written under `target/fuzz-findings/<target>/`.
//!
//! `cargo test -p agentstar-data --test fuzz` runs a bounded time (default 40 s in all,
//! split between targets; CI). `AGENTSTAR_FUZZ_SECS=1800` runs longer, `AGENTSTAR_FUZZ_SEED`
//! picks the seed, and `AGENTSTAR_FUZZ_ONLY=npz,urdf` restricts the targets.

use agentstar_data::capture::Capture;
use agentstar_data::gt::GroundTruth;
use agentstar_data::posefile::PoseFile;
use agentstar_data::urdf::load_urdf;
use agentstar_data::{images, meshio, npz};
use agentstar_scene::{build_scene, Limits, NoMeshFiles};
use std::path::{Path, PathBuf};
use std::time::Duration;

#[path = "../../../fuzz/harness.rs"]
mod harness;
use harness::{corpus_dir, fuzz, Run};

/// A capture directory for the targets that need one (`fuzz/corpus/capture/`), copied.
fn capture_copy(into: &Path) -> PathBuf {
    fn copy(from: &Path, to: &Path) {
        std::fs::create_dir_all(to).expect("dir");
        for e in std::fs::read_dir(from).expect("ls") {
            let e = e.expect("entry");
            let t = to.join(e.file_name());
            if e.path().is_dir() {
                copy(&e.path(), &t);
            } else {
                std::fs::copy(e.path(), &t).expect("copy");
            }
        }
    }
    let dst = into.join("cap");
    copy(&corpus_dir().join("capture"), &dst);
    dst
}

fn targets(work: &Path) -> Vec<(&'static str, Run)> {
    let cap = capture_copy(work);
    let cap_json = cap.clone();
    let cap_kf = cap.clone();
    let cams_dir = work.join("cams");
    {
        let c = capture_copy(&cams_dir);
        let _ = std::fs::remove_file(c.join("tracking/cameras.npz"));
    }
    let cams = cams_dir.join("cap");
    let files = work.join("files");
    std::fs::create_dir_all(&files).expect("dir");
    let mesh = agentstar_geom::primitives::cuboid(0.1, 0.1, 0.1).expect("box");
    std::fs::write(files.join("m.obj"), meshio::obj_text(&mesh, "m")).expect("mesh");
    let (f1, f2, f3, f4, f5) = (
        files.clone(),
        files.clone(),
        files.clone(),
        files.clone(),
        files.clone(),
    );
    let limits = Limits {
        max_wall_time: Duration::from_secs(2),
        ..Limits::default()
    };
    vec![
        (
            "scene",
            Box::new(move |b: &[u8]| {
                let _ = build_scene(&String::from_utf8_lossy(b), &NoMeshFiles, &limits);
            }) as Run,
        ),
        (
            "capture_json",
            Box::new(move |b: &[u8]| {
                std::fs::write(cap_json.join("capture.json"), b).expect("write");
                let _ = Capture::validate(&cap_json);
            }),
        ),
        (
            "keyframes",
            Box::new(move |b: &[u8]| {
                std::fs::write(cap_kf.join("tracking/keyframes.json"), b).expect("write");
                let _ = Capture::validate(&cap_kf);
            }),
        ),
        (
            "cameras_json",
            Box::new(move |b: &[u8]| {
                std::fs::write(cams.join("tracking/cameras.json"), b).expect("write");
                let _ = Capture::validate(&cams);
            }),
        ),
        (
            "npz",
            Box::new(|b: &[u8]| {
                let _ = npz::read_arrays_from(
                    b,
                    Path::new("f.npz"),
                    &["c2w", "intrinsics", "size", "local", "conf", "keep"],
                );
            }),
        ),
        (
            "npy",
            Box::new(|b: &[u8]| {
                let _ = npz::parse_npy(b, Path::new("f.npy"), "a");
            }),
        ),
        (
            "png",
            Box::new(move |b: &[u8]| {
                let p = f1.join("f.png");
                std::fs::write(&p, b).expect("write");
                let _ = images::image_size(&p);
                let _ = images::load_rgb(&p);
                let _ = images::load_mask(&p);
            }),
        ),
        (
            "jpeg",
            Box::new(move |b: &[u8]| {
                let p = f2.join("f.jpg");
                std::fs::write(&p, b).expect("write");
                let _ = images::image_size(&p);
                let _ = images::load_rgb(&p);
            }),
        ),
        (
            "pose",
            Box::new(move |b: &[u8]| {
                let p = f3.join("pose.json");
                std::fs::write(&p, b).expect("write");
                if let Ok(pf) = PoseFile::read(&p) {
                    let _ = pf.joint_defs();
                }
            }),
        ),
        (
            "gt",
            Box::new(move |b: &[u8]| {
                let p = f4.join("gt.json");
                std::fs::write(&p, b).expect("write");
                let _ = GroundTruth::load(&p);
            }),
        ),
        (
            "urdf",
            Box::new(move |b: &[u8]| {
                let p = f5.join("r.urdf");
                std::fs::write(&p, b).expect("write");
                let _ = load_urdf(&p);
            }),
        ),
        ("obj", Box::new(|b: &[u8]| drop(meshio::parse_obj(b)))),
        ("stl", Box::new(|b: &[u8]| drop(meshio::parse_stl(b)))),
        ("ply", Box::new(|b: &[u8]| drop(meshio::parse_ply(b)))),
        ("glb", Box::new(|b: &[u8]| drop(meshio::parse_glb(b)))),
    ]
}

#[test]
fn parsers_never_panic_or_hang_on_mutated_inputs() {
    let work = tempfile::tempdir().expect("tmp");
    fuzz(targets(work.path()), 40);
}
