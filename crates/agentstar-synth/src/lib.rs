//! Synthetic captures with ground truth, rendered by our renderer and fully seeded.
//!
//! An object of the library ([`objects`]) is built from its scene script, moved along a
//! motion of one of three kinds ([`Motion`]), seen by a camera with its own trajectory, and
//! rendered with per-part colours, a checker texture fixed to each part (so frames are
//! informative to a model), shading, a textured background and rendered hand occluders
//! ([`hand`]). Masks are exact visible-region masks, optionally with boundary noise of a
//! segmenter; hand masks are the visible hand pixels; depth (planar, metres) is exact.
//!
//! No I/O: the caller writes the capture (`agentstar synth`) or uses it in memory
//! (`agentstar bench`).

pub mod environment;
pub mod generate;
pub mod hand;
pub mod motion;
pub mod noise;
pub mod objects;
pub mod textured;

pub use motion::Motion;
pub use objects::{Appearance, AxialGroup, Family, ObjectSpec, Symmetry, LIBRARY};

use agentstar_geom::pose::{ObjectPose, Rigid, Similarity};
use agentstar_geom::{ObjectModel, PinholeCamera, Point3, UnitQuaternion, Vector3};
use agentstar_optim::Rng;
use agentstar_render::raster::Affine;
use agentstar_render::{render_full, BitMask, Instance, PosedModel, NO_PART};
use image::{Rgb, RgbImage};

#[derive(Debug, thiserror::Error)]
pub enum SynthError {
    #[error("unknown object `{name}`; the library has: {known}; generated objects are named gen-N (N a seed, e.g. gen-0)")]
    UnknownObject { name: String, known: String },
    #[error("the scene script of `{object}` does not build: {message}")]
    Scene { object: String, message: String },
    #[error("invalid configuration: {0}")]
    Config(String),
}

/// What to synthesise.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthConfig {
    /// An object name of [`LIBRARY`], or a generated object's (`gen-N`, [`generate`]).
    pub object: String,
    /// The motion; `None` takes the object's family default.
    pub motion: Option<Motion>,
    pub frames: usize,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    /// Rendered hand occluders (with their masks).
    pub hands: bool,
    /// Amplitude in pixels of segmenter-like noise on mask boundaries (0: exact masks).
    pub mask_noise_px: f64,
    /// Write depth; `None`: only for the static-object orbit (as iTACO has depth).
    pub depth: Option<bool>,
    /// The principal point (pixels); `None`: the image centre.
    pub principal_point: Option<(f64, f64)>,
    /// Hands as in hand-held captures made elsewhere: larger, reaching across the object, and
    /// hiding up to this fraction of its silhouette (placed again farther out while they hide
    /// more). `None`: the default grips at the object's rim.
    pub hand_coverage_max: Option<f64>,
    /// In-between frames rendered between consecutive keyframes (0: none). With them the
    /// keyframes are `between + 1` video frames apart (else 5), and are the same keyframes
    /// as without them.
    pub between: usize,
}

impl Default for SynthConfig {
    fn default() -> Self {
        SynthConfig {
            object: "box".into(),
            motion: None,
            frames: 12,
            width: 320,
            height: 240,
            seed: 0,
            hands: true,
            mask_noise_px: 0.0,
            depth: None,
            principal_point: None,
            hand_coverage_max: None,
            between: 0,
        }
    }
}

/// One synthesised keyframe.
#[derive(Debug, Clone)]
pub struct SynthFrame {
    /// File name, e.g. `000010.png`.
    pub name: String,
    pub frame_index: i64,
    pub time_s: f64,
    pub world_from_camera: Rigid,
    /// Ground truth: object (canonical) to camera, without the scale.
    pub camera_from_object: ObjectPose,
    /// Ground-truth joint states (radians, canonical units).
    pub states: Vec<f64>,
    pub rgb: RgbImage,
    /// The visible object (hands in front removed).
    pub mask: BitMask,
    /// The visible hand pixels, in frames where a hand was placed.
    pub hand: Option<BitMask>,
    /// Planar depth in metres of everything rendered (object and hands); NaN elsewhere.
    pub depth_m: Option<Vec<f32>>,
    /// The fraction of the object's silhouette hidden by hands (0 to 1).
    pub hand_coverage: f64,
}

/// A synthesised capture and everything needed to write it and its ground truth.
#[derive(Debug, Clone)]
pub struct SynthCapture {
    pub object: ObjectSpec,
    pub motion: Motion,
    pub seed: u64,
    /// Built from `object.script` (the "known model" of tracking).
    pub model: ObjectModel,
    /// Metres per canonical unit.
    pub scale: f64,
    pub camera: PinholeCamera,
    /// The keyframes.
    pub frames: Vec<SynthFrame>,
    /// The in-between frames (`SynthConfig::between` of them between consecutive keyframes),
    /// in temporal order: the same motion sampled densely.
    pub between: Vec<SynthFrame>,
    /// Rotations of the base part's frame that map the object onto itself (not the identity).
    pub symmetries: Vec<UnitQuaternion>,
}

impl SynthCapture {
    /// The object's rotation in the world between consecutive keyframes, degrees.
    pub fn step_angles_deg(&self) -> Vec<f64> {
        self.frames
            .windows(2)
            .map(|w| {
                let a = w[0].world_from_camera.rotation * w[0].camera_from_object.rotation;
                let b = w[1].world_from_camera.rotation * w[1].camera_from_object.rotation;
                (b * a.inverse()).angle().to_degrees()
            })
            .collect()
    }

    /// A short identifier: `object-motion-sSEED`.
    pub fn id(&self) -> String {
        format!(
            "{}-{}-s{}",
            self.object.name,
            self.motion.as_str(),
            self.seed
        )
    }
}

/// Builds a library object's model from its script.
pub fn build_object(spec: &ObjectSpec) -> Result<ObjectModel, SynthError> {
    agentstar_scene::build_scene(
        &spec.script,
        &agentstar_scene::NoMeshFiles,
        &agentstar_scene::Limits::default(),
    )
    .map(|b| b.model)
    .map_err(|e| SynthError::Scene {
        object: spec.name.to_string(),
        message: e.to_string(),
    })
}

/// Synthesises a capture. Deterministic for a configuration.
pub fn synthesize(cfg: &SynthConfig) -> Result<SynthCapture, SynthError> {
    let spec = ObjectSpec::resolve(&cfg.object).ok_or_else(|| SynthError::UnknownObject {
        name: cfg.object.clone(),
        known: ObjectSpec::names().join(", "),
    })?;
    let spec = &spec;
    if cfg.frames < 2 || cfg.frames > 2000 {
        return Err(SynthError::Config(format!(
            "frames must be 2 to 2000, got {}",
            cfg.frames
        )));
    }
    if !(16..=4096).contains(&cfg.width) || !(16..=4096).contains(&cfg.height) {
        return Err(SynthError::Config(format!(
            "image size must be 16 to 4096 pixels a side, got {}×{}",
            cfg.width, cfg.height
        )));
    }
    if !(cfg.mask_noise_px.is_finite() && (0.0..=8.0).contains(&cfg.mask_noise_px)) {
        return Err(SynthError::Config(format!(
            "mask noise must be 0 to 8 pixels, got {}",
            cfg.mask_noise_px
        )));
    }
    if cfg.between > 59 || cfg.frames * (cfg.between + 1) > 20_000 {
        return Err(SynthError::Config(format!(
            "between must be 0 to 59 in-between frames a keyframe step, and {} keyframes with {} between each make too long a video (at most 20,000 frames)",
            cfg.frames, cfg.between
        )));
    }
    if let Some(c) = cfg.hand_coverage_max {
        if !(c.is_finite() && (0.0..=0.95).contains(&c)) {
            return Err(SynthError::Config(format!(
                "the hands' largest coverage must be 0 to 0.95, got {c}"
            )));
        }
    }
    let (cx, cy) = cfg
        .principal_point
        .unwrap_or((0.5 * cfg.width as f64, 0.5 * cfg.height as f64));
    if !(cx.is_finite() && cy.is_finite())
        || cx < 0.0
        || cy < 0.0
        || cx > cfg.width as f64
        || cy > cfg.height as f64
    {
        return Err(SynthError::Config(format!(
            "the principal point ({cx}, {cy}) lies outside the {}×{} image",
            cfg.width, cfg.height
        )));
    }
    let model = build_object(spec)?;
    let motion = cfg.motion.unwrap_or(Motion::default_for(spec.family));
    let depth = cfg.depth.unwrap_or(motion == Motion::StaticOrbit);
    let (w, h) = (cfg.width, cfg.height);
    let f = 0.95 * w.max(h) as f64;
    let camera =
        PinholeCamera::new(f, f, cx, cy, w, h).map_err(|e| SynthError::Config(e.to_string()))?;
    let scale = spec.size_m;
    // Seeds of independent streams, so that adding a hand does not change the motion.
    let mut motion_rng = Rng::new(cfg.seed.wrapping_mul(0x9E37_79B9).wrapping_add(1));
    let mut hand_rng = Rng::new(cfg.seed.wrapping_mul(0x85EB_CA6B).wrapping_add(2));
    let mut look_rng = Rng::new(cfg.seed.wrapping_mul(0xC2B2_AE35).wrapping_add(3));
    let traj = motion::trajectory(motion, &model, scale, &camera, cfg.frames, &mut motion_rng);
    let hand_mesh = hand::hand_mesh();
    let hand_part = agentstar_geom::Part::new("hand", hand_mesh, hand::SKIN);
    let hand_scale = hand::hand_scale_for(scale);
    let background = Background::new(&mut look_rng, w, h);
    let light = Vector3::new(-0.3 + 0.6 * look_rng.uniform(), -0.6, -1.0).normalize();
    let colors: Vec<[f32; 3]> = model.parts.iter().map(|p| p.color).collect();
    let radius = 0.5
        * model
            .posed_bounds(&model.tree.rest_states())
            .extent()
            .norm()
        * scale;
    let hand_probability = match motion {
        Motion::HandHeld => 0.85,
        Motion::RigidSteps => 0.6,
        Motion::StaticOrbit => 0.35,
        Motion::HardHeld => 0.85,
    };
    let hand_phase = hand_rng.range(0.0, std::f64::consts::TAU);
    // Every keyframe's hands are drawn first, in the order the keyframes were always drawn in,
    // so that a capture with in-between frames has the same keyframes as one without.
    let hand_plans: Vec<Vec<HandPlan>> = (0..traj.len())
        .map(|_| {
            let mut count = 0;
            if cfg.hands && hand_rng.uniform() < hand_probability {
                count = if matches!(motion, Motion::HandHeld | Motion::HardHeld)
                    && hand_rng.uniform() < 0.4
                {
                    2
                } else {
                    1
                };
            }
            (0..count)
                .map(|_| match cfg.hand_coverage_max {
                    None => HandPlan {
                        jitter: hand_rng.range(-0.2, 0.2),
                        reach: 0.0,
                        size: hand_scale,
                    },
                    Some(_) => HandPlan {
                        jitter: hand_rng.range(-0.4, 0.4),
                        reach: hand_rng.range(0.2, 1.0),
                        size: hand_scale * hand_rng.range(1.0, 1.5),
                    },
                })
                .collect()
        })
        .collect();
    let scene = FrameScene {
        cfg,
        spec,
        model: &model,
        camera: &camera,
        scale,
        radius,
        hand_part: &hand_part,
        hand_phase,
        background: &background,
        light: &light,
        colors: &colors,
        depth,
    };
    let stride = if cfg.between == 0 {
        5
    } else {
        cfg.between as i64 + 1
    };
    let mut between = Vec::new();
    if cfg.between > 0 {
        for (k, pair) in traj.windows(2).enumerate() {
            for j in 1..=cfg.between {
                let s = j as f64 / (cfg.between + 1) as f64;
                let step = motion::between_step(&pair[0], &pair[1], &model, scale, s);
                // Each hand stays with its keyframe's grip until halfway, then takes the next
                // one's; the grip turns with the motion in between.
                let hands = &hand_plans[if s < 0.5 { k } else { k + 1 }];
                let frame_index = stride * k as i64 + j as i64;
                between.push(scene.render(
                    step,
                    k as f64 + s,
                    hands,
                    FrameSeeds::between(cfg.seed, frame_index),
                    frame_index,
                ));
            }
        }
    }
    let frames: Vec<SynthFrame> = traj
        .into_iter()
        .zip(&hand_plans)
        .enumerate()
        .map(|(k, (step, hands))| {
            scene.render(
                step,
                k as f64,
                hands,
                FrameSeeds::keyframe(cfg.seed, k),
                stride * k as i64,
            )
        })
        .collect();
    let symmetries = spec.symmetry.rotations();
    Ok(SynthCapture {
        object: spec.clone(),
        motion,
        seed: cfg.seed,
        model,
        scale,
        camera,
        frames,
        between,
        symmetries,
    })
}

/// One hand of a frame: its grip's turn about the object (added to the sequence's phase),
/// how far it reaches across the object, and its size.
#[derive(Debug, Clone, Copy)]
struct HandPlan {
    jitter: f64,
    reach: f64,
    size: f64,
}

/// The seeds of a frame's mask noise and film grain.
#[derive(Debug, Clone, Copy)]
struct FrameSeeds {
    mask_noise: u64,
    grain: u32,
}

impl FrameSeeds {
    fn keyframe(seed: u64, k: usize) -> FrameSeeds {
        FrameSeeds {
            mask_noise: seed ^ (k as u64).wrapping_mul(0x2545_F491_4F6C_DD1D),
            grain: seed as u32 ^ k as u32,
        }
    }
    /// Distinct from every keyframe's seeds.
    fn between(seed: u64, frame_index: i64) -> FrameSeeds {
        FrameSeeds {
            mask_noise: seed
                ^ ((1u64 << 40) + frame_index as u64).wrapping_mul(0x2545_F491_4F6C_DD1D),
            grain: seed as u32 ^ (0x8000_0000 | frame_index as u32),
        }
    }
}

/// What every frame of a capture shares.
struct FrameScene<'a> {
    cfg: &'a SynthConfig,
    spec: &'a ObjectSpec,
    model: &'a ObjectModel,
    camera: &'a PinholeCamera,
    scale: f64,
    radius: f64,
    hand_part: &'a agentstar_geom::Part,
    hand_phase: f64,
    background: &'a Background,
    light: &'a Vector3,
    colors: &'a [[f32; 3]],
    depth: bool,
}

impl FrameScene<'_> {
    /// Renders one frame at `step`; `key_position` is its place in keyframes (fractional
    /// between them), which turns the hands' grips.
    fn render(
        &self,
        step: motion::Step,
        key_position: f64,
        hands: &[HandPlan],
        seeds: FrameSeeds,
        frame_index: i64,
    ) -> SynthFrame {
        let (cfg, model, scale, camera) = (self.cfg, self.model, self.scale, self.camera);
        let posed = PosedModel::new(
            model,
            &step.states,
            &step.camera_from_object.with_scale(scale),
        );
        let mut instances: Vec<Instance<'_>> = posed.instances.clone();
        let n_parts = instances.len() as u16;
        let hand_count = hands.len();
        let centre = step
            .camera_from_object
            .with_scale(scale)
            .transform_point(&model.posed_bounds(&step.states).center());
        let phi_of = |i: usize, plan: &HandPlan| {
            self.hand_phase + 0.35 * key_position + std::f64::consts::PI * i as f64 + plan.jitter
        };
        let buffers = match cfg.hand_coverage_max {
            None => {
                for (i, plan) in hands.iter().enumerate() {
                    let pose = hand::grip_pose(&centre, self.radius, phi_of(i, plan), plan.size);
                    instances.push(hand_instance(self.hand_part, &pose, n_parts + i as u16));
                }
                render_full(camera, &instances)
            }
            Some(max_coverage) => {
                // Hands reaching across the object; moved out until they hide at most
                // `max_coverage` of it, dropped if they still hide more.
                let alone = render_full(camera, &instances);
                let full = alone.part.iter().filter(|&&p| p < n_parts).count().max(1);
                let mut chosen = alone;
                for attempt in 0..=6 {
                    if hands.is_empty() {
                        break;
                    }
                    let mut with_hands = instances.clone();
                    if attempt < 6 {
                        for (i, plan) in hands.iter().enumerate() {
                            let pose = hand::reach_pose(
                                &centre,
                                self.radius,
                                phi_of(i, plan),
                                plan.size,
                                plan.reach + 0.2 * attempt as f64,
                            );
                            with_hands.push(hand_instance(
                                self.hand_part,
                                &pose,
                                n_parts + i as u16,
                            ));
                        }
                    }
                    let b = render_full(camera, &with_hands);
                    let visible = b.part.iter().filter(|&&p| p < n_parts).count();
                    chosen = b;
                    if 1.0 - visible as f64 / full as f64 <= max_coverage {
                        break;
                    }
                }
                chosen
            }
        };
        let full_count = if cfg.hand_coverage_max.is_some() || hand_count > 0 {
            render_full(camera, &posed.instances)
                .part
                .iter()
                .filter(|&&p| p < n_parts)
                .count()
        } else {
            0
        };
        let visible_count = buffers.part.iter().filter(|&&p| p < n_parts).count();
        let hand_coverage = if full_count == 0 {
            0.0
        } else {
            (1.0 - visible_count as f64 / full_count as f64).max(0.0)
        };
        let (mut mask, hand_mask) = object_and_hand_masks(&buffers, n_parts);
        let mut hand_mask = (hand_count > 0).then_some(hand_mask);
        if cfg.mask_noise_px > 0.0 {
            let seed = seeds.mask_noise;
            mask = noise::jitter_boundary(&mask, cfg.mask_noise_px, seed);
            hand_mask = hand_mask.map(|m| noise::jitter_boundary(&m, cfg.mask_noise_px, seed + 1));
        }
        // Colour: textured, shaded parts and hands over the background.
        let part_from_camera =
            part_from_camera(model, &step.states, &step.camera_from_object, scale);
        let foreground = Foreground {
            camera,
            light: self.light,
            appearance: self.spec.appearance,
            colors: self.colors,
            part_from_camera: &part_from_camera,
            n_parts,
        };
        let rgb = foreground.paint(
            &buffers,
            |x, y| 0.03 * (noise::hash01(x, y, seeds.grain) - 0.5),
            |x, y| self.background.at(x, y),
        );
        let depth_m = self.depth.then(|| {
            buffers
                .depth
                .iter()
                .map(|&z| if z.is_finite() { z } else { f32::NAN })
                .collect()
        });
        SynthFrame {
            name: format!("{frame_index:06}.png"),
            frame_index,
            time_s: frame_index as f64 / 30.0,
            world_from_camera: step.world_from_camera,
            camera_from_object: step.camera_from_object,
            states: step.states,
            rgb,
            mask,
            hand: hand_mask,
            depth_m,
            hand_coverage,
        }
    }
}

pub(crate) fn hand_instance<'a>(
    hand: &'a agentstar_geom::Part,
    pose: &Similarity,
    part_id: u16,
) -> Instance<'a> {
    Instance {
        mesh: &hand.mesh,
        bounds: hand.bounds,
        camera_from_mesh: Affine::from_similarity(pose),
        edges: hand.edges.as_deref().map(|e| e.as_slice()),
        open_edges: hand.open_edges.as_deref().map(|e| e.as_slice()),
        planes: hand.planes.as_deref().map(|q| q.as_slice()),
        part_id,
    }
}

/// What colours a foreground pixel: the object's parts (their albedo under `appearance`, at
/// the pixel's point in the part's rest coordinates) and, from part id `n_parts` on, the
/// hands (skin); both Lambert-shaded under `light`. Captures and room clips share it.
pub(crate) struct Foreground<'a> {
    pub camera: &'a PinholeCamera,
    pub light: &'a Vector3,
    pub appearance: Appearance,
    pub colors: &'a [[f32; 3]],
    pub part_from_camera: &'a [Similarity],
    pub n_parts: u16,
}

impl Foreground<'_> {
    /// The display colour (gamma applied) of pixel (`x`, `y`), which must not be background.
    pub fn shade(&self, buffers: &agentstar_render::RenderBuffers, x: u32, y: u32) -> [f64; 3] {
        let i = (y * buffers.width + x) as usize;
        let p = buffers.part[i];
        let n = buffers.normal[i];
        let l = self.light;
        let lambert = (-(n[0] as f64 * l.x + n[1] as f64 * l.y + n[2] as f64 * l.z)).max(0.0);
        let shading = 0.3 + 0.7 * lambert;
        if p < self.n_parts {
            let z = buffers.depth[i] as f64;
            let q = Point3::from(self.camera.ray_direction(x as f64 + 0.5, y as f64 + 0.5) * z);
            let local = self.part_from_camera[p as usize].transform_point(&q);
            let albedo = albedo(self.appearance, p as usize, &local, self.colors[p as usize]);
            srgb(albedo.map(|a| a * shading))
        } else {
            srgb(hand::SKIN.map(|v| v as f64 * shading))
        }
    }

    /// The image: each pixel's colour, the foreground's where the buffers show a part or a
    /// hand and `background`'s elsewhere, plus `grain` at that pixel, in 8 bits.
    pub fn paint(
        &self,
        buffers: &agentstar_render::RenderBuffers,
        grain: impl Fn(u32, u32) -> f64,
        background: impl Fn(u32, u32) -> [f64; 3],
    ) -> RgbImage {
        let (w, h) = (buffers.width, buffers.height);
        let mut rgb = RgbImage::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let grain = grain(x, y);
                let c = if buffers.part[(y * w + x) as usize] == NO_PART {
                    background(x, y)
                } else {
                    self.shade(buffers, x, y)
                };
                rgb.put_pixel(
                    x,
                    y,
                    Rgb([
                        to_u8(c[0] + grain),
                        to_u8(c[1] + grain),
                        to_u8(c[2] + grain),
                    ]),
                );
            }
        }
        rgb
    }
}

/// The object's mask (part ids below `n_parts`) and the hands' (the ids from `n_parts` on).
pub(crate) fn object_and_hand_masks(
    buffers: &agentstar_render::RenderBuffers,
    n_parts: u16,
) -> (BitMask, BitMask) {
    let (w, h) = (buffers.width, buffers.height);
    let object = BitMask::from_fn(w, h, |x, y| buffers.part[(y * w + x) as usize] < n_parts);
    let hands = BitMask::from_fn(w, h, |x, y| {
        let p = buffers.part[(y * w + x) as usize];
        p != NO_PART && p >= n_parts
    });
    (object, hands)
}

/// Each part's frame from the camera's: the inverse of the scaled object pose composed with
/// the part's transform at `states`.
pub(crate) fn part_from_camera(
    model: &ObjectModel,
    states: &[f64],
    camera_from_object: &ObjectPose,
    scale: f64,
) -> Vec<Similarity> {
    model
        .tree
        .part_transforms(states)
        .iter()
        .map(|t| {
            camera_from_object
                .with_scale(scale)
                .compose(&Similarity::from_rigid(t))
                .inverse()
        })
        .collect()
}

/// The albedo (linear RGB) of part `part` at `local` (its canonical rest coordinates).
fn albedo(appearance: Appearance, part: usize, local: &Point3, color: [f32; 3]) -> [f64; 3] {
    let c = color.map(|v| v as f64);
    match appearance {
        Appearance::Checker => {
            let t = checker(local);
            c.map(|v| v * t)
        }
        Appearance::Plain => c,
        Appearance::Printed(paint) => paint(part, local),
    }
}

/// Linear RGB to display values (gamma 2.2).
pub(crate) fn srgb(c: [f64; 3]) -> [f64; 3] {
    c.map(|v| v.max(0.0).powf(1.0 / 2.2))
}

pub(crate) fn to_u8(v: f64) -> u8 {
    (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8
}

/// A checker fixed to the part (six squares per canonical unit): 1.0 or 0.78.
pub(crate) fn checker(p: &Point3) -> f64 {
    let k = (6.0 * p.x).floor() + (6.0 * p.y).floor() + (6.0 * p.z).floor();
    if (k as i64).rem_euclid(2) == 0 {
        1.0
    } else {
        0.78
    }
}

/// A seeded background: a vertical gradient of a random hue with soft blobs and grain.
struct Background {
    top: [f64; 3],
    bottom: [f64; 3],
    blobs: Vec<(f64, f64, f64, f64)>,
    seed: u32,
    height: f64,
}

impl Background {
    fn new(rng: &mut Rng, w: u32, h: u32) -> Background {
        let mut colour = || {
            let g = rng.range(0.35, 0.75);
            [
                g + rng.range(-0.08, 0.08),
                g + rng.range(-0.08, 0.08),
                g + rng.range(-0.08, 0.08),
            ]
        };
        let (top, bottom) = (colour(), colour());
        let blobs = (0..6)
            .map(|_| {
                (
                    rng.range(0.0, w as f64),
                    rng.range(0.0, h as f64),
                    rng.range(0.08, 0.3) * w as f64,
                    rng.range(-0.12, 0.12),
                )
            })
            .collect();
        Background {
            top,
            bottom,
            blobs,
            seed: rng.next_u64() as u32,
            height: h as f64,
        }
    }

    fn at(&self, x: u32, y: u32) -> [f64; 3] {
        let t = y as f64 / self.height.max(1.0);
        let mut c = [0.0; 3];
        for (i, v) in c.iter_mut().enumerate() {
            *v = self.top[i] * (1.0 - t) + self.bottom[i] * t;
        }
        let mut b = 0.0;
        for &(bx, by, r, a) in &self.blobs {
            let d2 = ((x as f64 - bx).powi(2) + (y as f64 - by).powi(2)) / (r * r);
            b += a * (-d2).exp();
        }
        let coarse = 0.06 * (noise::hash01(x / 6, y / 6, self.seed) - 0.5);
        c.map(|v| v + b + coarse)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_library_object_builds_in_its_canonical_frame() {
        let mut problems = Vec::new();
        for spec in LIBRARY {
            let model = match build_object(spec) {
                Ok(m) => m,
                Err(e) => {
                    problems.push(e.to_string());
                    continue;
                }
            };
            let r = model.canonical_report();
            if !(0.8..=1.25).contains(&r.longest_side) {
                problems.push(format!("{}: longest side {}", spec.name, r.longest_side));
            }
            if Vector3::from(r.center).norm() > 0.08 {
                problems.push(format!("{}: centre {:?}", spec.name, r.center));
            }
            for p in &model.parts {
                if !p.watertight {
                    problems.push(format!("{}: part {} is not closed", spec.name, p.name));
                }
            }
            if model.tree.joints().is_empty() != (spec.family == Family::Hot3d) {
                problems.push(format!(
                    "{}: HOT3D objects are rigid, the others articulated",
                    spec.name
                ));
            }
        }
        assert!(problems.is_empty(), "{problems:#?}");
    }

    #[test]
    fn checker_alternates_per_cell() {
        assert_eq!(checker(&Point3::new(0.01, 0.01, 0.01)), 1.0);
        assert_eq!(checker(&Point3::new(0.2, 0.01, 0.01)), 0.78);
        assert_eq!(checker(&Point3::new(-0.01, 0.01, 0.01)), 0.78);
    }
}
