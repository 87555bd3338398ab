//! Benchmark suites: which synthetic sequences to run.

use crate::BenchError;
use agentstar_synth::{Motion, SynthConfig, LIBRARY};

/// One sequence of a suite: the synthesiser's configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceSpec {
    pub synth: SynthConfig,
}

impl SequenceSpec {
    pub fn new(
        object: &str,
        motion: Option<Motion>,
        frames: usize,
        size: (u32, u32),
        seed: u64,
    ) -> Self {
        SequenceSpec {
            synth: SynthConfig {
                object: object.into(),
                motion,
                frames,
                width: size.0,
                height: size.1,
                seed,
                ..SynthConfig::default()
            },
        }
    }
    pub fn with_mask_noise(mut self, px: f64) -> Self {
        self.synth.mask_noise_px = px;
        self
    }
}

/// The hard suite's objects, in order.
pub const HARD_OBJECTS: [&str; 7] = [
    "labelcan",
    "plainbottle",
    "printmug",
    "kettle",
    "twinlaptop",
    "drawerbox",
    "shears",
];

/// Objects of the library in no suite: made by hand for one figure (`highmug`: the printed
/// mug with its handle high, for `scripts/track_bake_figures.sh`).
pub const UNSUITED_OBJECTS: [&str; 1] = ["highmug"];

/// One sequence of the hard suite: built like captures made outside this project (20
/// keyframes at 640×480, the `hard-held` motion of about 40° mean and up to 150° between
/// keyframes with a moving camera, hands hiding up to 60% of the object, 2 px segmenter-like
/// noise on the masks, the principal point 38 px right of and 22 px above the centre).
pub fn hard_sequence(object: &str, seed: u64) -> SequenceSpec {
    let (w, h) = (640u32, 480u32);
    SequenceSpec {
        synth: SynthConfig {
            object: object.into(),
            motion: Some(Motion::HardHeld),
            frames: 20,
            width: w,
            height: h,
            seed,
            hands: true,
            mask_noise_px: 2.0,
            depth: Some(false),
            principal_point: Some((0.5 * w as f64 + 38.0, 0.5 * h as f64 - 22.0)),
            hand_coverage_max: Some(0.6),
            between: 0,
        },
    }
}

/// The generated objects of the `general` suite: `gen-N` for N in this range of generator
/// seeds ([`agentstar_synth::generate`]). Nothing is tuned to any of them; to look at a single
/// case, pick its seed (`--only gen-7`), and to look at others, run over another range
/// ([`general_suite_over`], `bench --suite general --objects 24..48`), never change a
/// constant of the generator or the tracker.
pub const GENERAL_OBJECT_SEEDS: std::ops::Range<u64> = 0..24;

/// The capture seeds of each generated object in the `general` suite.
pub const GENERAL_CAPTURE_SEEDS: usize = 3;

/// The `general` suite: every generated object of [`GENERAL_OBJECT_SEEDS`] in
/// [`GENERAL_CAPTURE_SEEDS`] captures of the hard suite's kind ([`hard_sequence`]), seeds
/// `1000 + 10·N + k`.
pub fn general_suite() -> Vec<SequenceSpec> {
    general_suite_over(GENERAL_OBJECT_SEEDS, GENERAL_CAPTURE_SEEDS)
}

/// The `general` suite over other generated objects: `gen-N` for N in `objects`, each in
/// `captures` captures (seeds `1000 + 10·N + k`, k < `captures`). Objects no one has looked
/// at measure the tracker without the bias of the cases studied (`bench --suite general
/// --objects 24..48 --captures 1`).
pub fn general_suite_over(objects: std::ops::Range<u64>, captures: usize) -> Vec<SequenceSpec> {
    objects
        .flat_map(|n| {
            (0..captures as u64).map(move |k| {
                hard_sequence(
                    &agentstar_synth::generate::object_name(n),
                    1000 + 10 * n + k,
                )
            })
        })
        .collect()
}

/// The most captures of one generated object (`1000 + 10·N + k` stays N's own for k < 10).
pub const GENERAL_MAX_CAPTURES: usize = 10;

/// `START..END`, a range of generator seeds (END exclusive, START < END).
pub fn parse_seed_range(text: &str) -> Result<std::ops::Range<u64>, BenchError> {
    let bad = || {
        BenchError::Invalid(format!(
            "`{text}` is not a range of generator seeds: write START..END, START < END (as 24..48)"
        ))
    };
    let (start, end) = text.trim().split_once("..").ok_or_else(bad)?;
    let start: u64 = start.trim().parse().map_err(|_| bad())?;
    let end: u64 = end.trim().parse().map_err(|_| bad())?;
    if start >= end {
        return Err(bad());
    }
    Ok(start..end)
}

/// The suites: `quick` (one sequence per dataset family, small images, for CI), `full`
/// (every object of the default library with its dataset's motion, 15 keyframes as HOT3D's
/// protocol, plus sequences with segmenter noise on the masks) and `hard` (objects whose
/// outlines repeat under rotations or part swaps, in captures like real hand-held ones; see
/// [`hard_sequence`]; run by hand, not in CI) and `general` (objects generated at random from
/// primitives and joints, in the hard suite's captures, three seeds each; [`general_suite`];
/// by hand). `None` for an unknown name.
pub fn suite(name: &str) -> Option<Vec<SequenceSpec>> {
    match name {
        "quick" => Some(vec![
            SequenceSpec::new("box", None, 8, (240, 180), 2),
            SequenceSpec::new("mug", None, 8, (240, 180), 2),
            SequenceSpec::new("microwave", None, 8, (240, 180), 3),
        ]),
        "full" => {
            let mut v: Vec<SequenceSpec> = LIBRARY
                .iter()
                .filter(|o| {
                    !HARD_OBJECTS.contains(&o.name.as_ref())
                        && !UNSUITED_OBJECTS.contains(&o.name.as_ref())
                })
                .enumerate()
                .map(|(i, o)| SequenceSpec::new(&o.name, None, 15, (320, 240), 100 + i as u64))
                .collect();
            v.push(SequenceSpec::new("laptop", None, 15, (320, 240), 200).with_mask_noise(1.5));
            v.push(SequenceSpec::new("bottle", None, 15, (320, 240), 201).with_mask_noise(1.5));
            v.push(SequenceSpec::new("oven", None, 15, (320, 240), 202).with_mask_noise(1.5));
            Some(v)
        }
        "hard" => Some(
            HARD_OBJECTS
                .iter()
                .enumerate()
                .map(|(i, o)| hard_sequence(o, 300 + i as u64))
                .collect(),
        ),
        "general" => Some(general_suite()),
        _ => None,
    }
}

/// The names of the suites.
pub const SUITES: [&str; 4] = ["quick", "full", "hard", "general"];
