//! The requests of `turntable`, `pose-diff` and `temporal`, as the MCP tools of the same
//! names take them and the commands flatten them.

use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The joint states a turntable shows.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct TurntableArgs {
    /// Joint states to show: `representative` (each joint's min, median and max over the
    /// keyframes; the default), `all` (every distinct state: many sheets), keyframes in
    /// the frame grammar (`000010,000040`), or states given outright (degrees, canonical
    /// units; joints not named at rest): `hinge:90|hinge:0;drawer:0.2`, one sheet each, also
    /// before any pose is tracked.
    #[arg(long)]
    #[schemars(length(min = 1, max = 4000))]
    pub states: Option<String>,
    /// Acknowledge the joint-limit warnings this reply finds (a joint at its lower or upper
    /// limit in many keyframes): later replies summarise each in one line while it stays the
    /// same joint, limit and keyframes; a new one still warns in full.
    // The agent's tools keep the record; not a flag of the command.
    #[arg(skip)]
    #[serde(default)]
    pub acknowledge_limits: bool,
}

impl TurntableArgs {
    /// The states to show (`representative` when none are named).
    pub fn states(&self) -> &str {
        self.states
            .as_deref()
            .map(str::trim)
            .filter(|s| !s.is_empty())
            .unwrap_or("representative")
    }
}

/// The two keyframes whose poses `pose-diff` compares.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct PoseDiffArgs {
    #[arg(long, help = "The first keyframe.")]
    #[schemars(length(min = 1))]
    pub a: String,
    #[arg(long, help = "The second keyframe.")]
    #[schemars(length(min = 1))]
    pub b: String,
}

/// How the `temporal` report's rows are sorted.
#[derive(clap::Args, Debug, Clone, PartialEq, Deserialize, Serialize, JsonSchema)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct TemporalArgs {
    /// e.g. vel.rot, accel.rot, vel.trans, <joint>.vel
    #[arg(
        long,
        help = "Sort by |value| descending: vel.rot, vel.trans, vel.radial, accel.rot, accel.trans, accel.radial, <joint>.vel, <joint>.accel."
    )]
    pub sort_by: Option<String>,
    /// Acknowledge the joint-limit warnings this reply finds, as `turntable`'s
    /// `acknowledge_limits` does.
    // The agent's tools keep the record; not a flag of the command.
    #[arg(skip)]
    #[serde(default)]
    pub acknowledge_limits: bool,
}

/// The part of a frame a view shows: around the object mask (and the model's silhouette)
/// with the view's margin, or a box given in frame pixels. Written `mask` or
/// `x0,y0,x1,y1` (corners, x1 and y1 exclusive), on the command line and in a tool's
/// arguments alike.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Crop {
    #[default]
    Mask,
    /// Frame pixels `[x0, x1) × [y0, y1)`.
    Box { x0: u32, y0: u32, x1: u32, y1: u32 },
}

impl std::str::FromStr for Crop {
    type Err = String;
    fn from_str(s: &str) -> Result<Crop, String> {
        let s = s.trim();
        if s.eq_ignore_ascii_case("mask") {
            return Ok(Crop::Mask);
        }
        let v: Vec<&str> = s.split(',').map(str::trim).collect();
        let parsed: Result<Vec<u32>, _> = v.iter().map(|p| p.parse::<u32>()).collect();
        match (v.len(), parsed) {
            (4, Ok(n)) if n[2] > n[0] && n[3] > n[1] => Ok(Crop::Box {
                x0: n[0],
                y0: n[1],
                x1: n[2],
                y1: n[3],
            }),
            (4, Ok(_)) => Err(format!(
                "crop `{s}`: x1 must exceed x0 and y1 exceed y0 (corners x0,y0,x1,y1 in frame pixels)"
            )),
            _ => Err(format!(
                "crop `{s}`: give `mask` or a box `x0,y0,x1,y1` of whole frame pixels"
            )),
        }
    }
}

impl std::fmt::Display for Crop {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Crop::Mask => write!(f, "mask"),
            Crop::Box { x0, y0, x1, y1 } => write!(f, "{x0},{y0},{x1},{y1}"),
        }
    }
}

impl Serialize for Crop {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for Crop {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Crop, D::Error> {
        let s = String::deserialize(d)?;
        s.parse().map_err(serde::de::Error::custom)
    }
}

impl JsonSchema for Crop {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "Crop".into()
    }
    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "type": "string",
            "pattern": "^\\s*([Mm][Aa][Ss][Kk]|\\d+\\s*,\\s*\\d+\\s*,\\s*\\d+\\s*,\\s*\\d+)\\s*$",
            "description": "`mask` (around the object mask and the model, with the margin) or `x0,y0,x1,y1`: a box in frame pixels (x1, y1 exclusive), e.g. around a 10-pixel detail."
        })
    }
}

impl Crop {
    /// The window `[x0, y0, width, height]` in a `width`×`height` frame: a box clamped to
    /// the frame (an error when it lies wholly outside), or `around` for `mask`.
    pub fn window(
        &self,
        width: u32,
        height: u32,
        around: Option<[u32; 4]>,
    ) -> Result<[u32; 4], String> {
        match *self {
            Crop::Mask => Ok(around.unwrap_or([0, 0, width, height])),
            Crop::Box { x0, y0, x1, y1 } => {
                let (x1, y1) = (x1.min(width), y1.min(height));
                if x0 >= x1 || y0 >= y1 {
                    return Err(format!(
                        "crop {self} lies outside the {width}×{height} frame"
                    ));
                }
                Ok([x0, y0, x1 - x0, y1 - y0])
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crops_parse_print_and_clamp() {
        assert_eq!("mask".parse::<Crop>(), Ok(Crop::Mask));
        let c: Crop = " 10, 20 ,30,40".parse().expect("box");
        assert_eq!(c.to_string(), "10,20,30,40");
        assert_eq!(c.window(100, 100, None), Ok([10, 20, 20, 20]));
        assert_eq!(c.window(25, 100, None), Ok([10, 20, 15, 20]));
        assert!(c.window(10, 100, None).is_err());
        assert!("30,20,10,40".parse::<Crop>().is_err());
        assert!("10,20,30".parse::<Crop>().is_err());
        assert!("-1,0,3,3".parse::<Crop>().is_err());
        assert_eq!(
            Crop::Mask.window(8, 6, Some([1, 1, 2, 2])),
            Ok([1, 1, 2, 2])
        );
        assert_eq!(Crop::Mask.window(8, 6, None), Ok([0, 0, 8, 6]));
        let json = serde_json::to_string(&c).expect("json");
        assert_eq!(json, "\"10,20,30,40\"");
        assert_eq!(serde_json::from_str::<Crop>(&json).expect("back"), c);
        assert!(serde_json::from_str::<Crop>("\"0,0,0,0\"").is_err());
    }
}
