//! `agentstar synth OUT`: a seeded synthetic capture with ground truth, rendered by our
//! renderer, from the object library and one of three motions; `--list` shows the library.

use crate::common::print_json;
use agentstar_data::capture_writer::{write_capture, CaptureInfo, FrameOut};
use agentstar_data::gt::{model_ground_truth, GroundTruth};
use agentstar_data::posefile::{FramePose, PoseFile};
use agentstar_synth::{synthesize, Motion, ObjectSpec, SynthCapture, SynthConfig, LIBRARY};
use anyhow::{anyhow, bail, Context, Result};
use serde_json::json;
use std::path::{Path, PathBuf};
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(
    after_help = "Example:\n  agentstar synth /tmp/laptop --object laptop --frames 16 --seed 3\n  agentstar track /tmp/laptop --model /tmp/laptop/model/scene.rhai --scale-from /tmp/laptop/model/pose.json --out /tmp/laptop-run/pose.json"
)]
pub struct Args {
    /// Directory to write the capture into (must not exist or be empty).
    #[arg(required_unless_present = "list")]
    out: Option<PathBuf>,
    /// Object of the library (see --list).
    #[arg(long, default_value = "box")]
    object: String,
    /// Motion: handheld, rigid-steps, static-orbit or hard-held (default: the object's dataset's).
    #[arg(long)]
    motion: Option<String>,
    /// Number of keyframes.
    #[arg(long, default_value_t = 12)]
    frames: usize,
    /// Image size WxH.
    #[arg(long, default_value = "320x240")]
    size: String,
    /// Seed of every random choice.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// No hand occluders.
    #[arg(long)]
    no_hands: bool,
    /// Segmenter-like noise on mask boundaries, in pixels (0 to 8).
    #[arg(long, default_value_t = 0.0)]
    mask_noise: f64,
    /// Write depth (default: only for the static-object orbit).
    #[arg(long, overrides_with = "no_depth")]
    depth: bool,
    /// Write no depth.
    #[arg(long)]
    no_depth: bool,
    /// Principal point CX,CY in pixels (default: the image centre).
    #[arg(long)]
    principal_point: Option<String>,
    /// Hands that reach across the object, hiding up to this fraction of it (0 to 0.95).
    #[arg(long)]
    hand_coverage: Option<f64>,
    /// Also write K in-between frames between consecutive keyframes (the same motion sampled
    /// densely, with hands and mask noise in every frame); keyframes are then K + 1 video
    /// frames apart (else 5), and are the same keyframes as without in-between frames.
    #[arg(long, default_value_t = 0, value_name = "K")]
    between: usize,
    /// Also write the true model as mesh files under `model/`, as a scan or a CAD export
    /// would give it (a rigid object's parts merged at rest into one mesh): `textured.glb`
    /// and `textured.obj` (with `textured.mtl`, `map_Kd textured_t0.png`), its print painted
    /// into a texture at --mesh-texels per model unit; and `plain.glb`, the same mesh in one
    /// colour (for `track --bake`).
    #[arg(long)]
    mesh_models: bool,
    /// Texels per model unit of the mesh models' texture.
    #[arg(long, default_value_t = 256.0, requires = "mesh_models")]
    mesh_texels: f64,
    /// List the object library and the motions, then exit.
    #[arg(long)]
    list: bool,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

/// Parses `WxH`.
pub fn parse_size(s: &str) -> Result<(u32, u32)> {
    let (w, h) = s
        .split_once(['x', 'X', '×'])
        .ok_or_else(|| anyhow!("--size `{s}`: expected WxH, e.g. 320x240"))?;
    Ok((
        w.trim()
            .parse()
            .with_context(|| format!("--size `{s}`: width"))?,
        h.trim()
            .parse()
            .with_context(|| format!("--size `{s}`: height"))?,
    ))
}

/// Parses `CX,CY` (pixels).
fn parse_principal_point(s: &str) -> Result<(f64, f64)> {
    let (x, y) = s
        .split_once(',')
        .ok_or_else(|| anyhow!("--principal-point `{s}`: expected CX,CY, e.g. 358,218"))?;
    let num = |v: &str, what: &str| -> Result<f64> {
        v.trim()
            .parse()
            .with_context(|| format!("--principal-point `{s}`: {what}"))
    };
    Ok((num(x, "CX")?, num(y, "CY")?))
}

pub fn parse_motion(s: &str) -> Result<Motion> {
    Motion::parse(s).ok_or_else(|| {
        anyhow!(
            "unknown motion `{s}`; choose one of {}",
            Motion::ALL.map(|m| m.as_str()).join(", ")
        )
    })
}

/// Writes a synthetic capture to `dir`: the capture, `gt.json` with its meshes, and the known
/// model with its true poses under `model/` (`scene.rhai`, `pose.json`).
pub fn write_synth(dir: &Path, s: &SynthCapture) -> Result<()> {
    let mut all: Vec<&agentstar_synth::SynthFrame> = s.frames.iter().chain(&s.between).collect();
    all.sort_by_key(|f| f.frame_index);
    let frames: Vec<FrameOut<'_>> = all
        .into_iter()
        .map(|f| FrameOut {
            name: &f.name,
            frame_index: Some(f.frame_index),
            time_s: Some(f.time_s),
            camera: &s.camera,
            world_from_camera: &f.world_from_camera,
            rgb: &f.rgb,
            mask: &f.mask,
            hand: f.hand.as_ref(),
            depth_m: f.depth_m.as_deref(),
        })
        .collect();
    let info = CaptureInfo {
        dataset: Some(format!("agentstar-synth/{}", s.object.family.as_str())),
        // What made the capture, not what is in it: the object's name and scale are the
        // truth (`gt.json`, `model/`), which an agent tracking the capture must not read
        // (play-test 22's agent found them here).
        source: Some(json!({
            "producer": "agentstar synth", "motion": s.motion.as_str(),
            "seed": s.seed, "between": s.between.len(),
        })),
        keyframes: (!s.between.is_empty())
            .then(|| s.frames.iter().map(|f| f.name.clone()).collect()),
    };
    write_capture(dir, &frames, &info, |root| {
        let truth: Vec<_> = s
            .frames
            .iter()
            .map(|f| (f.name.clone(), f.camera_from_object, f.states.clone()))
            .collect();
        let (file, meshes) = model_ground_truth(&s.model, s.scale, &truth, &s.symmetries);
        GroundTruth::from_parts(&root.join("gt.json"), file, meshes).write(root)?;
        let model_dir = root.join("model");
        agentstar_data::atomic::write_atomic(
            &model_dir.join("scene.rhai"),
            s.object.script.as_bytes(),
        )?;
        let capture = agentstar_data::capture::Capture::open(root)
            .map_err(|e| agentstar_data::DataError::invalid(root, e.to_string()))?;
        let poses: Vec<FramePose> = s
            .frames
            .iter()
            .map(|f| FramePose {
                generalised: agentstar_geom::GenPose::new(f.camera_from_object, f.states.clone()),
                seeded: false,
                moved: true,
            })
            .collect();
        let mut pf =
            PoseFile::initial(&capture, &s.model.tree, s.scale, &poses[0].generalised.pose);
        pf.set_frames(&capture, &s.model.tree, &poses);
        let between: Vec<(&str, agentstar_geom::GenPose)> = s
            .between
            .iter()
            .map(|f| {
                let pose = agentstar_geom::GenPose::new(f.camera_from_object, f.states.clone());
                (f.name.as_str(), pose)
            })
            .collect();
        pf.set_between(&s.model.tree, between.iter().map(|(n, p)| (*n, p)));
        pf.write(&model_dir.join("pose.json"))?;
        Ok(())
    })
    .map_err(|e| anyhow!(e.to_string()))
}

/// The true model as mesh files in `dir`: `textured.glb`, `textured.obj` (+ `.mtl`, texture)
/// and `plain.glb` ([`agentstar_synth::textured`]); refused for a model with joints.
fn write_mesh_models(dir: &Path, s: &SynthCapture, texels_per_unit: f64) -> Result<()> {
    use agentstar_synth::textured::{plain_mesh_model, textured_model};
    let what = |e: agentstar_synth::SynthError| anyhow!("--mesh-models: {}: {e}", s.object.name);
    let textured = textured_model(&s.model, s.object.appearance, texels_per_unit).map_err(what)?;
    agentstar_data::export::write_glb(&textured, &dir.join("textured.glb"))?;
    agentstar_data::export::write_obj(&textured, &dir.join("textured.obj"))?;
    let plain = plain_mesh_model(&s.model).map_err(what)?;
    agentstar_data::export::write_glb(&plain, &dir.join("plain.glb"))?;
    Ok(())
}

/// A one-line description of a synthetic capture.
pub fn describe(s: &SynthCapture) -> String {
    let hands = s.frames.iter().filter(|f| f.hand.is_some()).count();
    format!(
        "{} ({}, {}): {} frames{} {}×{}, {} joint(s), hands in {hands}, depth {}",
        s.object.name,
        s.object.family.as_str(),
        s.motion.as_str(),
        s.frames.len(),
        match s.between.len() {
            0 => String::new(),
            n => format!(" (and {n} in-between)"),
        },
        s.camera.width,
        s.camera.height,
        s.model.tree.joints().len(),
        if s.frames.iter().any(|f| f.depth_m.is_some()) {
            "yes"
        } else {
            "no"
        }
    )
}

pub fn run(a: Args) -> Result<ExitCode> {
    if a.list {
        let rows: Vec<_> = LIBRARY
            .iter()
            .map(|o| {
                json!({"object": o.name, "family": o.family.as_str(), "size_m": o.size_m,
                       "default_motion": Motion::default_for(o.family).as_str(),
                       "symmetry": format!("{:?}", o.symmetry),
                       "description": o.script.lines().next().unwrap_or("").trim_start_matches("// ")})
            })
            .collect();
        if a.json {
            print_json(&json!({"objects": rows, "motions": Motion::ALL.map(|m| m.as_str())}))?;
        } else {
            println!(
                "| object | family | size (m) | default motion | what |\n|---|---|---|---|---|"
            );
            for r in &rows {
                println!(
                    "| {} | {} | {} | {} | {} |",
                    r["object"].as_str().unwrap_or(""),
                    r["family"].as_str().unwrap_or(""),
                    r["size_m"],
                    r["default_motion"].as_str().unwrap_or(""),
                    r["description"].as_str().unwrap_or("")
                );
            }
            println!("motions: {}", Motion::ALL.map(|m| m.as_str()).join(", "));
        }
        return Ok(ExitCode::SUCCESS);
    }
    let Some(out) = a.out else {
        bail!("give the output directory (or --list)")
    };
    if ObjectSpec::resolve(&a.object).is_none() {
        bail!(
            "unknown object `{}`; the library has: {}; generated objects are named gen-N (N a seed, e.g. gen-0)",
            a.object,
            ObjectSpec::names().join(", ")
        );
    }
    let (width, height) = parse_size(&a.size)?;
    let cfg = SynthConfig {
        object: a.object.clone(),
        motion: a.motion.as_deref().map(parse_motion).transpose()?,
        frames: a.frames,
        width,
        height,
        seed: a.seed,
        hands: !a.no_hands,
        mask_noise_px: a.mask_noise,
        principal_point: a
            .principal_point
            .as_deref()
            .map(parse_principal_point)
            .transpose()?,
        hand_coverage_max: a.hand_coverage,
        between: a.between,
        depth: if a.depth {
            Some(true)
        } else if a.no_depth {
            Some(false)
        } else {
            None
        },
    };
    if a.mesh_models && !(a.mesh_texels.is_finite() && a.mesh_texels > 0.0) {
        bail!(
            "--mesh-texels {}: give a positive number of texels per model unit",
            a.mesh_texels
        );
    }
    let s = synthesize(&cfg)?;
    write_synth(&out, &s)?;
    if a.mesh_models {
        write_mesh_models(&out.join("model"), &s, a.mesh_texels)?;
    }
    if a.json {
        print_json(&json!({
            "capture": out, "object": s.object.name, "family": s.object.family.as_str(),
            "motion": s.motion.as_str(), "frames": s.frames.len(),
            "between_frames": s.between.len(), "seed": s.seed,
            "scale_m": s.scale, "model": out.join("model/scene.rhai"), "poses": out.join("model/pose.json"),
            "gt": out.join("gt.json"),
        }))?;
    } else {
        println!("wrote {}: {}", out.display(), describe(&s));
        println!(
            "  ground truth: {}; known model and true poses: {}, {}",
            out.join("gt.json").display(),
            out.join("model/scene.rhai").display(),
            out.join("model/pose.json").display()
        );
    }
    Ok(ExitCode::SUCCESS)
}
