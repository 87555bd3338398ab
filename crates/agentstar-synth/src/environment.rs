//! A textured static room around a hand-held object, seen by a moving camera: clips for
//! testing camera estimation (structure from motion on the background, with the object and
//! hand masked out) against the true cameras.
//!
//! The room is an axis-aligned box (world frame, +Z up, metres) whose floor, walls and
//! ceiling carry a seeded texture: smooth value noise at two scales and spots of random
//! colour and size, the blob-like structure a feature detector finds on real walls and
//! furniture (or one flat colour per wall for the textureless case). Background pixels are
//! ray-cast exactly into the box (2×2 samples per pixel); the object and the gripping hand
//! are rendered by our renderer and shaded as in [`crate::synthesize`].
//!
//! Every frame of the clip is kept (the frames between keyframes matter to structure from
//! motion); keyframes are every `keyframe_every`-th frame.

use crate::hand;
use crate::motion::{held_step, Step};
use crate::noise::hash01;
use crate::objects::ObjectSpec;
use crate::{
    build_object, hand_instance, object_and_hand_masks, part_from_camera, srgb, Foreground,
    SynthError, SynthFrame,
};
use agentstar_geom::camera::look_at;
use agentstar_geom::pose::Rigid;
use agentstar_geom::{ObjectModel, PinholeCamera, Point3, UnitQuaternion, Vector3};
use agentstar_optim::Rng;
use agentstar_render::{render_full, Instance, PosedModel, NO_PART};
use std::f64::consts::{PI, TAU};

/// What the room's surfaces look like.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Walls {
    /// Noise and spots: plenty of features.
    Textured,
    /// One flat colour per surface: only the room's edges have structure.
    Plain,
    /// Texture with the statistics of photographs of a cluttered room: multi-octave noise
    /// with a 1/f amplitude spectrum (from 1.3 m down to 1 cm), a gravel floor (dense small
    /// stones of random tone), brick walls (courses of offset bricks with mortar lines),
    /// and framed pictures (straight edges, their own colour and finer noise) on the walls.
    Photographic,
}

/// How the camera moves.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CameraPath {
    /// An orbit of 50°–70° about the object with hand-held wobble (position, aim and roll).
    OrbitWobble,
    /// A camera on a tripod: the same pose in every frame.
    Static,
    /// The camera turns in place (a pan of about 30°) and the object is carried along in
    /// front of it: no parallax in the background.
    PureRotation,
}

/// What to synthesise.
#[derive(Debug, Clone, PartialEq)]
pub struct RoomConfig {
    /// An object name of [`crate::LIBRARY`].
    pub object: String,
    /// Every frame of the clip (keyframes and the frames between them).
    pub frames: usize,
    pub keyframe_every: usize,
    pub width: u32,
    pub height: u32,
    pub seed: u64,
    pub walls: Walls,
    pub camera: CameraPath,
    /// Degrees the object turns in the world per frame (about a drifting axis).
    pub object_turn_deg_per_frame: f64,
    /// A hand holds the object (it drifts a little and its joints move); without one the
    /// object stands still in the room (no drift, joints at rest) and only its turn, if any,
    /// moves it.
    pub hand: bool,
    /// The orbit's sweep in degrees (`OrbitWobble`); `None`: 50° to 70°, drawn.
    pub orbit_deg: Option<f64>,
}

impl Default for RoomConfig {
    fn default() -> Self {
        RoomConfig {
            object: "box".into(),
            frames: 40,
            keyframe_every: 4,
            width: 320,
            height: 240,
            seed: 0,
            walls: Walls::Textured,
            camera: CameraPath::OrbitWobble,
            object_turn_deg_per_frame: 2.5,
            hand: true,
            orbit_deg: None,
        }
    }
}

/// A rendered clip: every frame with its true camera, object pose and masks.
#[derive(Debug, Clone)]
pub struct RoomClip {
    pub object: &'static ObjectSpec,
    pub model: ObjectModel,
    /// Metres per canonical unit.
    pub scale: f64,
    pub camera: PinholeCamera,
    /// Every frame; `frames[k].frame_index == k`.
    pub frames: Vec<SynthFrame>,
    pub keyframe_every: usize,
    pub room: Room,
}

impl RoomClip {
    /// The keyframes (every `keyframe_every`-th frame, from the first).
    pub fn keyframes(&self) -> impl Iterator<Item = &SynthFrame> {
        self.frames.iter().step_by(self.keyframe_every.max(1))
    }
}

/// The room: an axis-aligned box in the world frame (metres) and the look of its surfaces.
#[derive(Debug, Clone, PartialEq)]
pub struct Room {
    pub min: Point3,
    pub max: Point3,
    pub walls: Walls,
    /// Linear RGB base colour of each surface (−X, +X, −Y, +Y, floor, ceiling).
    colours: [[f64; 3]; 6],
    seed: u32,
}

impl Room {
    fn new(walls: Walls, rng: &mut Rng) -> Room {
        let mut colours = [[0.0; 3]; 6];
        for c in &mut colours {
            let g = rng.range(0.3, 0.6);
            *c = [
                g + rng.range(-0.1, 0.1),
                g + rng.range(-0.1, 0.1),
                g + rng.range(-0.1, 0.1),
            ];
        }
        Room {
            min: Point3::new(-1.8 - rng.range(0.0, 0.4), -2.0 - rng.range(0.0, 0.4), -0.9),
            max: Point3::new(1.8 + rng.range(0.0, 0.4), 2.0 + rng.range(0.0, 0.4), 1.6),
            walls,
            colours,
            seed: rng.next_u64() as u32,
        }
    }

    /// Where a ray from inside the room leaves it: the surface index (−X, +X, −Y, +Y, floor,
    /// ceiling), the distance along `dir` and the hit point.
    pub fn hit(&self, origin: &Point3, dir: &Vector3) -> Option<(usize, f64, Point3)> {
        let mut best: Option<(usize, f64)> = None;
        for axis in 0..3 {
            let d = dir[axis];
            if d.abs() < 1e-12 {
                continue;
            }
            let (bound, surface) = if d > 0.0 {
                (self.max[axis], 2 * axis + 1)
            } else {
                (self.min[axis], 2 * axis)
            };
            let t = (bound - origin[axis]) / d;
            if t > 0.0 && best.is_none_or(|(_, bt)| t < bt) {
                best = Some((surface, t));
            }
        }
        best.map(|(s, t)| (s, t, origin + dir * t))
    }

    /// Linear RGB albedo (with the surface's constant shading) at a point of a surface.
    pub fn colour(&self, surface: usize, p: &Point3) -> [f64; 3] {
        // The surface's own 2-D coordinates: the two axes other than its normal.
        let axis = surface / 2;
        let (u, v) = match axis {
            0 => (p.y, p.z),
            1 => (p.x, p.z),
            _ => (p.x, p.y),
        };
        let base = self.colours[surface];
        let shade = [0.85, 0.95, 0.9, 1.0, 0.8, 1.05][surface];
        let seed = self.seed ^ (surface as u32).wrapping_mul(0x9E37_79B9);
        let mut c = base;
        match self.walls {
            Walls::Plain => {}
            Walls::Textured => {
                let n =
                    0.16 * value_noise(u, v, 0.35, seed) + 0.1 * value_noise(u, v, 0.08, seed ^ 1);
                for (i, x) in c.iter_mut().enumerate() {
                    *x += n * (1.0 + 0.3 * i as f64 - 0.3);
                }
                if let Some(spot) = spot_at(u, v, seed ^ 2) {
                    c = spot;
                }
            }
            Walls::Photographic => c = photographic(surface, u, v, base, seed),
        }
        c.map(|x| (x * shade).clamp(0.0, 1.0))
    }
}

/// Smooth value noise in [−1, 1] on a lattice of `cell` metres.
fn value_noise(u: f64, v: f64, cell: f64, seed: u32) -> f64 {
    let (gu, gv) = (u / cell, v / cell);
    let (iu, iv) = (gu.floor(), gv.floor());
    let (fu, fv) = (gu - iu, gv - iv);
    let s = |t: f64| t * t * (3.0 - 2.0 * t);
    let lattice = |du: f64, dv: f64| {
        let x = (iu + du) as i64 as u32;
        let y = (iv + dv) as i64 as u32;
        2.0 * hash01(x, y, seed) - 1.0
    };
    let (su, sv) = (s(fu), s(fv));
    let a = lattice(0.0, 0.0) * (1.0 - su) + lattice(1.0, 0.0) * su;
    let b = lattice(0.0, 1.0) * (1.0 - su) + lattice(1.0, 1.0) * su;
    a * (1.0 - sv) + b * sv
}

/// Octaves of the 1/f noise: cell sizes in metres, each half the one before.
const OCTAVES: [f64; 8] = [1.3, 0.65, 0.32, 0.16, 0.08, 0.04, 0.02, 0.01];

/// Noise whose amplitude is proportional to the wavelength (a 1/f amplitude spectrum, as
/// photographs of natural scenes have), in about [−1, 1].
fn pink_noise(u: f64, v: f64, seed: u32) -> f64 {
    let mut sum = 0.0;
    for (i, cell) in OCTAVES.iter().enumerate() {
        sum += cell / OCTAVES[0] * value_noise(u, v, *cell, seed.wrapping_add(i as u32 * 7919));
    }
    // The amplitudes sum to just under 2.
    0.5 * sum
}

/// Linear RGB of a photographic surface at its coordinates (u, v) in metres: 1/f noise on
/// every surface; gravel on the floor, bricks on the walls along X, and framed pictures on
/// every wall.
fn photographic(surface: usize, u: f64, v: f64, base: [f64; 3], seed: u32) -> [f64; 3] {
    let n = pink_noise(u, v, seed);
    let tint = value_noise(u, v, 0.5, seed ^ 5);
    let mut c = [
        base[0] * (1.0 + 0.55 * n) + 0.05 * tint,
        base[1] * (1.0 + 0.55 * n),
        base[2] * (1.0 + 0.55 * n) - 0.05 * tint,
    ];
    match surface {
        4 => {
            // Gravel: stones of 1.5 to 4 cm, each its own tone, darker in the gaps.
            if let Some(stone) = stone_at(u, v, 0.035, seed ^ 3) {
                let g = 0.6 + 0.8 * stone;
                c = c.map(|x| x * g);
            } else {
                c = c.map(|x| 0.45 * x);
            }
        }
        0 | 1 => {
            // Bricks of 21 × 6.5 cm in courses offset by half a brick; 1 cm of mortar.
            let (bw, bh, mortar) = (0.22, 0.075, 0.01);
            let row = (v / bh).floor();
            let shift = if row as i64 % 2 == 0 { 0.0 } else { 0.5 * bw };
            let col = ((u + shift) / bw).floor();
            let (fu, fv) = (u + shift - col * bw, v - row * bh);
            if fu < mortar || fv < mortar {
                c = [0.62 + 0.1 * n, 0.6 + 0.1 * n, 0.55 + 0.1 * n];
            } else {
                let h = hash01(col as i64 as u32, row as i64 as u32, seed ^ 4);
                let g = 0.75 + 0.5 * h;
                c = [c[0] * g * 1.25, c[1] * g * 0.85, c[2] * g * 0.7];
            }
        }
        _ => {}
    }
    if surface < 4 {
        if let Some(p) = picture_at(u, v, seed ^ 6) {
            c = p;
        }
    }
    c
}

/// A stone of a gravel bed on a grid of `cell` metres: its tone in [0, 1] where (u, v) lies
/// inside the stone of its cell, else `None` (the gap between stones).
fn stone_at(u: f64, v: f64, cell: f64, seed: u32) -> Option<f64> {
    let (iu, iv) = ((u / cell).floor(), (v / cell).floor());
    let (x, y) = (iu as i64 as u32, iv as i64 as u32);
    let h = |k: u32| hash01(x, y, seed.wrapping_add(k.wrapping_mul(0x2545_F491)));
    let (ru, rv) = (cell * (0.25 + 0.2 * h(1)), cell * (0.25 + 0.2 * h(2)));
    let cu = (iu + 0.5 + 0.15 * (h(3) - 0.5)) * cell;
    let cv = (iv + 0.5 + 0.15 * (h(4) - 0.5)) * cell;
    (((u - cu) / ru).powi(2) + ((v - cv) / rv).powi(2) <= 1.0).then(|| h(5))
}

/// A framed picture in half of the cells of 0.7 m: a dark frame, then the picture: a colour
/// of its own, a straight horizon between two tones and finer 1/f noise.
fn picture_at(u: f64, v: f64, seed: u32) -> Option<[f64; 3]> {
    const CELL: f64 = 0.7;
    let (iu, iv) = ((u / CELL).floor(), (v / CELL).floor());
    let (x, y) = (iu as i64 as u32, iv as i64 as u32);
    let h = |k: u32| hash01(x, y, seed.wrapping_add(k.wrapping_mul(0x68E3_1DA4)));
    if h(0) > 0.5 {
        return None;
    }
    let (half_w, half_h) = (CELL * (0.15 + 0.2 * h(1)), CELL * (0.12 + 0.2 * h(2)));
    let cu = (iu + 0.5) * CELL + (h(3) - 0.5) * (CELL - 2.0 * half_w);
    let cv = (iv + 0.5) * CELL + (h(4) - 0.5) * (CELL - 2.0 * half_h);
    let (du, dv) = ((u - cu).abs(), (v - cv).abs());
    if du > half_w || dv > half_h {
        return None;
    }
    let frame = 0.02;
    if du > half_w - frame || dv > half_h - frame {
        let g = 0.05 + 0.1 * h(5);
        return Some([g, g, g]);
    }
    // A horizon at a random height and slope splits the picture into two tones.
    let slope = h(6) - 0.5;
    let above = (v - cv) - slope * (u - cu) > (h(7) - 0.5) * half_h;
    let tone = |k: u32| 0.1 + 0.8 * h(k);
    let col = if above {
        [tone(8), tone(9), tone(10)]
    } else {
        [tone(11), tone(12), tone(13)]
    };
    let n = pink_noise(4.0 * u, 4.0 * v, seed ^ 9);
    Some(col.map(|x| x * (1.0 + 0.6 * n)))
}

/// A spot of random colour and radius in three cells of four (cells of 0.16 m), or none.
fn spot_at(u: f64, v: f64, seed: u32) -> Option<[f64; 3]> {
    const CELL: f64 = 0.16;
    let (iu, iv) = ((u / CELL).floor(), (v / CELL).floor());
    let (x, y) = (iu as i64 as u32, iv as i64 as u32);
    let h = |k: u32| hash01(x, y, seed.wrapping_add(k.wrapping_mul(0x27D4_EB2F)));
    if h(0) > 0.75 {
        return None;
    }
    let radius = CELL * (0.1 + 0.22 * h(1));
    let cu = (iu + 0.5 + (h(2) - 0.5) * (1.0 - 2.0 * radius / CELL)) * CELL;
    let cv = (iv + 0.5 + (h(3) - 0.5) * (1.0 - 2.0 * radius / CELL)) * CELL;
    if (u - cu).powi(2) + (v - cv).powi(2) > radius * radius {
        return None;
    }
    let bright = h(4) < 0.5;
    let g = if bright {
        0.75 + 0.2 * h(5)
    } else {
        0.04 + 0.12 * h(5)
    };
    Some([
        (g + 0.25 * (h(6) - 0.5)).clamp(0.0, 1.0),
        (g + 0.25 * (h(7) - 0.5)).clamp(0.0, 1.0),
        (g + 0.25 * (h(8) - 0.5)).clamp(0.0, 1.0),
    ])
}

/// A smooth wobble: two sinusoids of random frequency (0.4–2.2 cycles a clip) and phase.
struct Wobble {
    terms: [(f64, f64, f64); 2],
}

impl Wobble {
    fn new(rng: &mut Rng) -> Wobble {
        let mut term = |amp: f64| (amp, rng.range(0.4, 2.2), rng.range(0.0, TAU));
        Wobble {
            terms: [term(0.65), term(0.35)],
        }
    }
    /// In [−1, 1] at clip time `t` ∈ [0, 1].
    fn at(&self, t: f64) -> f64 {
        self.terms
            .iter()
            .map(|(a, f, p)| a * (TAU * f * t + p).sin())
            .sum()
    }
}

/// Synthesises a clip in a room. Deterministic for a configuration.
pub fn synthesize_room_clip(cfg: &RoomConfig) -> Result<RoomClip, SynthError> {
    let spec = ObjectSpec::find(&cfg.object).ok_or_else(|| SynthError::UnknownObject {
        name: cfg.object.clone(),
        known: ObjectSpec::names().join(", "),
    })?;
    if cfg.frames < 2 || cfg.frames > 2000 {
        return Err(SynthError::Config(format!(
            "frames must be 2 to 2000, got {}",
            cfg.frames
        )));
    }
    if cfg.keyframe_every == 0 || cfg.keyframe_every >= cfg.frames {
        return Err(SynthError::Config(format!(
            "keyframe_every must be 1 to frames − 1, got {}",
            cfg.keyframe_every
        )));
    }
    if !(64..=4096).contains(&cfg.width) || !(64..=4096).contains(&cfg.height) {
        return Err(SynthError::Config(format!(
            "image size must be 64 to 4096 pixels a side, got {}×{}",
            cfg.width, cfg.height
        )));
    }
    if !(cfg.object_turn_deg_per_frame.is_finite()
        && (0.0..=20.0).contains(&cfg.object_turn_deg_per_frame))
    {
        return Err(SynthError::Config(format!(
            "the object's turn must be 0 to 20 degrees a frame, got {}",
            cfg.object_turn_deg_per_frame
        )));
    }
    if let Some(d) = cfg.orbit_deg {
        if !(d.is_finite() && d > 0.0 && d <= 360.0) {
            return Err(SynthError::Config(format!(
                "the orbit's sweep must be above 0 and at most 360 degrees, got {d}"
            )));
        }
    }
    let model = build_object(spec)?;
    let (w, h) = (cfg.width, cfg.height);
    let f = 0.95 * w.max(h) as f64;
    let camera = PinholeCamera::new(f, f, 0.5 * w as f64, 0.5 * h as f64, w, h)
        .map_err(|e| SynthError::Config(e.to_string()))?;
    let scale = spec.size_m;
    let mut motion_rng = Rng::new(cfg.seed.wrapping_mul(0x9E37_79B9).wrapping_add(11));
    let mut look_rng = Rng::new(cfg.seed.wrapping_mul(0xC2B2_AE35).wrapping_add(13));
    let room = Room::new(cfg.walls, &mut look_rng);
    let light = Vector3::new(-0.3 + 0.6 * look_rng.uniform(), -0.6, -1.0).normalize();
    let n = cfg.frames;
    // The object spans about 40% of the image, leaving most of it to the background.
    let d = crate::motion::viewing_distance(&model, scale, &camera, 0.4);
    let moving = vec![true; model.tree.joints().len()];
    let mut states = crate::motion::joint_states(&model, n, &moving, &mut motion_rng);
    if !cfg.hand {
        // Nobody moves the object's joints.
        let rest = model.tree.rest_states();
        states.iter_mut().for_each(|s| *s = rest.clone());
    }
    let start = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), motion_rng.range(-PI, PI))
        * UnitQuaternion::from_axis_angle(&Vector3::x_axis(), motion_rng.range(-0.3, 0.3));
    let mut axis = crate::motion::random_axis(&mut motion_rng);
    let az0 = motion_rng.range(-PI, PI);
    let drawn_sweep = motion_rng.range(50.0, 70.0);
    let sweep = cfg.orbit_deg.unwrap_or(drawn_sweep).to_radians()
        * if motion_rng.uniform() < 0.5 {
            1.0
        } else {
            -1.0
        };
    let elevation = motion_rng.range(12.0, 25.0).to_radians();
    let wobble: Vec<Wobble> = (0..7).map(|_| Wobble::new(&mut motion_rng)).collect();
    let colors: Vec<[f32; 3]> = model.parts.iter().map(|p| p.color).collect();
    let radius = 0.5
        * model
            .posed_bounds(&model.tree.rest_states())
            .extent()
            .norm()
        * scale;
    let hand_part = agentstar_geom::Part::new("hand", hand::hand_mesh(), hand::SKIN);
    let hand_scale = hand::hand_scale_for(scale);
    let hand_phase = motion_rng.range(0.0, TAU);
    let mut rotation = start;
    let mut frames = Vec::with_capacity(n);
    for (k, st) in states.into_iter().enumerate() {
        let t = k as f64 / (n - 1) as f64;
        if k > 0 {
            axis = (axis + 0.15 * crate::motion::random_axis(&mut motion_rng)).normalize();
            rotation = crate::motion::turned(rotation, axis, cfg.object_turn_deg_per_frame);
        }
        let wob = |i: usize| wobble[i].at(t);
        // The object's centre: near the world origin, drifting a little in the hand.
        let mut centre = if cfg.hand {
            Point3::new(0.05 * d * wob(0), 0.05 * d * wob(1), 0.04 * d * wob(2))
        } else {
            Point3::origin()
        };
        let camera_from_world = match cfg.camera {
            CameraPath::OrbitWobble => {
                let az = az0 + sweep * t;
                let el = elevation + 0.06 * wob(3);
                let r = d * (1.0 + 0.06 * wob(4));
                let eye = Point3::new(
                    r * el.cos() * az.cos(),
                    r * el.cos() * az.sin(),
                    r * el.sin(),
                ) + Vector3::new(wob(5), wob(6), wob(0)) * 0.02 * d;
                let aim = Point3::new(0.03 * d * wob(6), 0.03 * d * wob(5), 0.03 * d * wob(4));
                let roll = UnitQuaternion::from_axis_angle(&Vector3::z_axis(), 0.035 * wob(2));
                let c = look_at(&eye, &aim, &Vector3::z());
                Rigid::from_parts((roll * c.translation.vector).into(), roll * c.rotation)
            }
            CameraPath::Static => {
                let eye = Point3::new(
                    d * elevation.cos() * az0.cos(),
                    d * elevation.cos() * az0.sin(),
                    d * elevation.sin(),
                );
                look_at(&eye, &Point3::origin(), &Vector3::z())
            }
            CameraPath::PureRotation => {
                // The eye stays put; the view pans and the object is carried in front of it.
                let eye = Point3::new(d * az0.cos(), d * az0.sin(), 0.0);
                let pan = az0 + PI + 0.5 * sweep * (t - 0.5);
                let dir = Vector3::new(pan.cos(), pan.sin(), -0.15).normalize();
                centre = eye + dir * d + (centre - Point3::origin());
                look_at(&eye, &(eye + dir), &Vector3::z())
            }
        };
        let Step {
            world_from_camera,
            camera_from_object,
            states: st,
        } = held_step(&model, scale, &camera_from_world, rotation, centre, st);
        let posed = PosedModel::new(&model, &st, &camera_from_object.with_scale(scale));
        // The whole silhouette, for the fraction the hand hides.
        let silhouette = render_full(&camera, &posed.instances)
            .part
            .iter()
            .filter(|&&p| p != NO_PART)
            .count();
        let mut instances: Vec<Instance<'_>> = posed.instances.clone();
        let n_parts = instances.len() as u16;
        let centre_cam = camera_from_object
            .with_scale(scale)
            .transform_point(&model.posed_bounds(&st).center());
        let phi = hand_phase + 0.6 * (TAU * t).sin();
        let hand_pose = hand::grip_pose(&centre_cam, radius, phi, hand_scale);
        if cfg.hand {
            instances.push(hand_instance(&hand_part, &hand_pose, n_parts));
        }
        let buffers = render_full(&camera, &instances);
        let (mask, hand_mask) = object_and_hand_masks(&buffers, n_parts);
        let part_from_camera = part_from_camera(&model, &st, &camera_from_object, scale);
        let eye = Point3::from(world_from_camera.translation.vector);
        let foreground = Foreground {
            camera: &camera,
            light: &light,
            appearance: spec.appearance,
            colors: &colors,
            part_from_camera: &part_from_camera,
            n_parts,
        };
        let rgb = foreground.paint(
            &buffers,
            |x, y| 0.012 * (hash01(x, y, cfg.seed as u32 ^ (k as u32) << 8) - 0.5),
            |x, y| {
                // 2×2 samples of the room.
                let mut acc = [0.0; 3];
                for (sx, sy) in [(0.25, 0.25), (0.75, 0.25), (0.25, 0.75), (0.75, 0.75)] {
                    let ray = world_from_camera.rotation
                        * camera.ray_direction(x as f64 + sx, y as f64 + sy);
                    if let Some((surface, _, q)) = room.hit(&eye, &ray) {
                        let c = room.colour(surface, &q);
                        for j in 0..3 {
                            acc[j] += 0.25 * c[j];
                        }
                    }
                }
                srgb(acc)
            },
        );
        let hand_coverage = 1.0 - mask.count() as f64 / silhouette.max(1) as f64;
        frames.push(SynthFrame {
            name: format!("{k:06}.png"),
            frame_index: k as i64,
            time_s: k as f64 / 30.0,
            world_from_camera,
            camera_from_object,
            states: st,
            rgb,
            mask,
            hand: cfg.hand.then_some(hand_mask),
            depth_m: None,
            hand_coverage,
        });
    }
    Ok(RoomClip {
        object: spec,
        model,
        scale,
        camera,
        frames,
        keyframe_every: cfg.keyframe_every,
        room,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn small(walls: Walls, camera: CameraPath) -> RoomClip {
        synthesize_room_clip(&RoomConfig {
            frames: 6,
            keyframe_every: 2,
            width: 160,
            height: 120,
            seed: 3,
            walls,
            camera,
            ..RoomConfig::default()
        })
        .expect("clip")
    }

    #[test]
    fn rays_leave_the_room_through_the_surface_they_point_at() {
        let room = Room::new(Walls::Textured, &mut Rng::new(1));
        let o = Point3::new(0.1, -0.2, 0.3);
        for (dir, surface) in [
            (Vector3::new(-1.0, 0.1, 0.1), 0),
            (Vector3::new(1.0, 0.1, -0.1), 1),
            (Vector3::new(0.1, -1.0, 0.1), 2),
            (Vector3::new(0.1, 1.0, 0.1), 3),
            (Vector3::new(0.1, 0.1, -1.0), 4),
            (Vector3::new(0.1, 0.1, 1.0), 5),
        ] {
            let (s, t, p) = room.hit(&o, &dir).expect("inside the room");
            assert_eq!(s, surface, "{dir:?}");
            assert!(t > 0.0);
            let axis = surface / 2;
            let bound = if surface % 2 == 0 {
                room.min[axis]
            } else {
                room.max[axis]
            };
            assert!((p[axis] - bound).abs() < 1e-9);
        }
    }

    /// Mean absolute difference of horizontally neighbouring background pixels.
    fn background_gradient(clip: &RoomClip) -> f64 {
        let f = &clip.frames[0];
        let (mut sum, mut count) = (0.0, 0usize);
        let hand = f.hand.as_ref().expect("a hand");
        for y in 0..f.rgb.height() {
            for x in 1..f.rgb.width() {
                let free = |x| !f.mask.get(x, y) && !hand.get(x, y);
                if free(x) && free(x - 1) {
                    let a = f.rgb.get_pixel(x, y).0[1] as f64;
                    let b = f.rgb.get_pixel(x - 1, y).0[1] as f64;
                    sum += (a - b).abs();
                    count += 1;
                }
            }
        }
        sum / count.max(1) as f64
    }

    #[test]
    fn textured_walls_have_structure_and_plain_walls_do_not() {
        let textured = background_gradient(&small(Walls::Textured, CameraPath::OrbitWobble));
        let plain = background_gradient(&small(Walls::Plain, CameraPath::OrbitWobble));
        let photographic =
            background_gradient(&small(Walls::Photographic, CameraPath::OrbitWobble));
        assert!(textured > 4.0 * plain, "textured {textured}, plain {plain}");
        assert!(
            photographic > 4.0 * plain,
            "photographic {photographic}, plain {plain}"
        );
        assert!(plain < 2.0, "plain {plain}");
    }

    #[test]
    fn photographic_texture_has_detail_at_every_scale() {
        // Mean absolute difference of the noise at points `d` metres apart grows with d
        // (structure at every scale), without saturating at the finest scale.
        let diff = |d: f64| {
            let mut sum = 0.0;
            for i in 0..400 {
                let (u, v) = (0.37 * i as f64, 0.11 * i as f64);
                sum += (pink_noise(u, v, 9) - pink_noise(u + d, v, 9)).abs();
            }
            sum / 400.0
        };
        let (fine, mid, coarse) = (diff(0.01), diff(0.08), diff(0.6));
        assert!(
            fine > 0.005 && fine < mid && mid < coarse,
            "{fine} {mid} {coarse}"
        );
    }

    #[test]
    fn without_a_hand_the_object_stands_still() {
        let clip = synthesize_room_clip(&RoomConfig {
            object: "microwave".into(),
            frames: 5,
            keyframe_every: 2,
            width: 160,
            height: 120,
            object_turn_deg_per_frame: 0.0,
            hand: false,
            orbit_deg: Some(90.0),
            ..RoomConfig::default()
        })
        .expect("clip");
        let world_from_object =
            |f: &SynthFrame| f.world_from_camera * f.camera_from_object.to_rigid();
        let first = world_from_object(&clip.frames[0]);
        for f in &clip.frames {
            assert!(f.hand.is_none());
            let w = world_from_object(f);
            assert!((w.translation.vector - first.translation.vector).norm() < 1e-9);
            assert!(w.rotation.angle_to(&first.rotation) < 1e-9);
            assert_eq!(f.states, clip.frames[0].states);
        }
        // The orbit sweeps the 90° asked for (the camera's heading about the vertical).
        let heading = |f: &SynthFrame| {
            let c = f.world_from_camera.translation.vector;
            c.y.atan2(c.x)
        };
        let sweep = (heading(&clip.frames[4]) - heading(&clip.frames[0]))
            .abs()
            .to_degrees();
        let sweep = sweep.min(360.0 - sweep);
        assert!((80.0..100.0).contains(&sweep), "{sweep}");
    }

    #[test]
    fn the_object_and_its_hand_stay_in_view_and_leave_most_of_the_background() {
        for path in [
            CameraPath::OrbitWobble,
            CameraPath::Static,
            CameraPath::PureRotation,
        ] {
            let clip = small(Walls::Textured, path);
            assert_eq!(clip.frames.len(), 6);
            assert_eq!(clip.keyframes().count(), 3);
            for f in &clip.frames {
                let total = (f.rgb.width() * f.rgb.height()) as f64;
                let object = f.mask.count() as f64 / total;
                let hand = f.hand.as_ref().map_or(0, |m| m.count()) as f64 / total;
                assert!(
                    object > 0.03 && object + hand < 0.45,
                    "{path:?} {object} {hand}"
                );
            }
        }
    }

    #[test]
    fn camera_paths_move_as_promised() {
        let centre = |f: &SynthFrame| f.world_from_camera.translation.vector;
        let spread = |clip: &RoomClip| {
            clip.frames
                .iter()
                .map(|f| (centre(f) - centre(&clip.frames[0])).norm())
                .fold(0.0, f64::max)
        };
        let turn = |clip: &RoomClip| {
            clip.frames
                .iter()
                .map(|f| {
                    (f.world_from_camera.rotation.inverse()
                        * clip.frames[0].world_from_camera.rotation)
                        .angle()
                })
                .fold(0.0, f64::max)
        };
        let orbit = small(Walls::Textured, CameraPath::OrbitWobble);
        assert!(spread(&orbit) > 0.2 && turn(&orbit) > 0.6, "orbit");
        let tripod = small(Walls::Textured, CameraPath::Static);
        assert!(spread(&tripod) < 1e-12 && turn(&tripod) < 1e-12, "static");
        let pan = small(Walls::Textured, CameraPath::PureRotation);
        assert!(spread(&pan) < 1e-12 && turn(&pan) > 0.3, "pure rotation");
    }
}
