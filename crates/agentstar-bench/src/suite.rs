//! Benchmark suites: which synthetic sequences to run.

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

/// The suites: `quick` (one sequence per dataset family, small images, for CI) and `full`
/// (every object of the library with its dataset's motion, 15 keyframes as HOT3D's
/// protocol, plus sequences with segmenter noise on the masks). `None` for an unknown name.
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
                .enumerate()
                .map(|(i, o)| SequenceSpec::new(o.name, None, 15, (320, 240), 100 + i as u64))
                .collect();
            v.push(SequenceSpec::new("laptop", None, 15, (320, 240), 200).with_mask_noise(1.5));
            v.push(SequenceSpec::new("bottle", None, 15, (320, 240), 201).with_mask_noise(1.5));
            v.push(SequenceSpec::new("oven", None, 15, (320, 240), 202).with_mask_noise(1.5));
            Some(v)
        }
        _ => None,
    }
}

/// The names of the suites.
pub const SUITES: [&str; 2] = ["quick", "full"];
