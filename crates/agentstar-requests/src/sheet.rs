//! What a search verb's candidate sheet shows: [`SheetView`] (`crop` and `zoom`), declared
//! once for the five search verbs (`sweep`, `apply`, `osweep`, `oapply`, `oapply-all`), and
//! [`WithSheet`], a search request with its sheet view beside it as one flat set of fields.
//!
//! The commands flatten [`SheetView`] once, among the options every search verb shares; the
//! tools take `WithSheet<Request>`. Why a wrapper and not `#[serde(flatten)]`: serde cannot
//! combine `flatten` with `deny_unknown_fields`, and a tool's arguments must refuse unknown
//! fields. So [`WithSheet`] deserialises by hand: it takes `crop` and `zoom` out of the
//! arguments' object into a [`SheetView`] and hands the rest to the request, whose own
//! `deny_unknown_fields` refuses anything else; its schema is the request's with the sheet
//! view's properties added at the top level (their descriptions and bounds come from
//! [`SheetView`]'s fields); it serialises as one flat object, so `to_args` gives the command
//! `--crop=…`/`--zoom=…` beside the request's flags.

use crate::Crop;
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use serde_json::{Map, Value};

/// The candidate sheet's tiles: the part of the frame they show and how far it is enlarged.
#[derive(
    clap::Args, Debug, Clone, Copy, PartialEq, Default, Deserialize, Serialize, JsonSchema,
)]
#[group(skip)]
#[serde(deny_unknown_fields)]
pub struct SheetView {
    /// The candidate sheet's tiles: `mask` (around the object and the finalists; the
    /// default) or a box `x0,y0,x1,y1` in frame pixels around a detail that decides.
    #[arg(
        long,
        help = "The part of the frame the candidate sheet's tiles show: `mask` (around the object mask and every finalist's silhouette; the default) or a box `x0,y0,x1,y1` in frame pixels, around a detail that decides (a drinking hole, a badge)"
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub crop: Option<Crop>,
    /// Output pixels per frame pixel on the sheet's tiles (1 to 8).
    #[arg(
        long,
        default_value = "1",
        help = "Output pixels per frame pixel on the candidate sheet's tiles (1 to 8; tiles are at least 320 px on their long side and at most 960 px)"
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schemars(range(min = 1.0, max = 8.0))]
    pub zoom: Option<f64>,
    /// The candidates the sheet draws, by rank: `6-11`, or one rank `7` (default the first
    /// six; more than six go on further pages).
    #[arg(
        long,
        help = "The candidates the candidate sheet draws, by rank: `6-11`, or one rank `7` (default the first six, or --sheet of them; more than six go on further pages): the ranks a first sheet listed as not drawn"
    )]
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub draw: Option<RankRange>,
}

/// Ranks `from` to `to` (inclusive) of a ranked list of candidates: written `6-11`, or `7`
/// for one.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RankRange {
    pub from: usize,
    pub to: usize,
}

impl RankRange {
    /// Whether `rank` lies in the range.
    pub fn contains(&self, rank: usize) -> bool {
        (self.from..=self.to).contains(&rank)
    }
}

/// The most ranks one `draw` range may name (a sheet page holds six candidates).
pub const MAX_DRAWN_RANKS: usize = 60;

impl std::str::FromStr for RankRange {
    type Err = String;
    fn from_str(s: &str) -> Result<RankRange, String> {
        let t = s.trim().trim_start_matches('#');
        let bad =
            || format!("draw `{s}`: give ranks as `6-11` (from and to, inclusive) or one rank `7`");
        let (from, to) = match t.split_once(['-', '–']) {
            Some((a, b)) => (
                a.trim()
                    .trim_start_matches('#')
                    .parse::<usize>()
                    .map_err(|_| bad())?,
                b.trim()
                    .trim_start_matches('#')
                    .parse::<usize>()
                    .map_err(|_| bad())?,
            ),
            None => {
                let k = t.parse::<usize>().map_err(|_| bad())?;
                (k, k)
            }
        };
        if to < from {
            return Err(format!("draw `{s}`: the range ends before it starts"));
        }
        if to - from + 1 > MAX_DRAWN_RANKS {
            return Err(format!(
                "draw `{s}`: at most {MAX_DRAWN_RANKS} ranks at once"
            ));
        }
        Ok(RankRange { from, to })
    }
}

impl std::fmt::Display for RankRange {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.from == self.to {
            write!(f, "{}", self.from)
        } else {
            write!(f, "{}-{}", self.from, self.to)
        }
    }
}

impl Serialize for RankRange {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(self)
    }
}

impl<'de> Deserialize<'de> for RankRange {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<RankRange, D::Error> {
        // A whole number is one rank, as its text is.
        match Value::deserialize(d)? {
            Value::String(s) => s.parse().map_err(serde::de::Error::custom),
            Value::Number(n) => n.to_string().parse().map_err(serde::de::Error::custom),
            other => Err(serde::de::Error::custom(format!(
                "draw {other}: give ranks as `6-11` or one rank `7`"
            ))),
        }
    }
}

impl JsonSchema for RankRange {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "RankRange".into()
    }
    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        schemars::json_schema!({
            "type": "string",
            "pattern": "^\\s*#?\\d+(\\s*[-–]\\s*#?\\d+)?\\s*$",
            "description": "Ranks `from-to` (inclusive), e.g. `6-11`, or one rank, e.g. `7`."
        })
    }
}

impl SheetView {
    /// The most output pixels per frame pixel a sheet's tiles take (the schema's `maximum`).
    pub const MAX_ZOOM: f64 = 8.0;

    /// The zoom to draw at (1 when none is given); a zoom under 1, past [`Self::MAX_ZOOM`]
    /// or not a number is refused, naming it.
    pub fn zoom(&self) -> Result<f64, String> {
        let zoom = self.zoom.unwrap_or(1.0);
        if zoom.is_finite() && (1.0..=Self::MAX_ZOOM).contains(&zoom) {
            Ok(zoom)
        } else {
            Err(format!(
                "zoom {zoom}: output pixels per frame pixel, from 1 to {}",
                Self::MAX_ZOOM
            ))
        }
    }
}

/// A search request with its candidate sheet's view, as one flat object: the arguments of
/// the `sweep`, `apply`, `osweep`, `oapply` and `oapply_all` tools (see the module's docs
/// for why this is written by hand).
#[derive(Debug, Clone, PartialEq)]
pub struct WithSheet<T> {
    pub request: T,
    pub sheet: SheetView,
}

impl<T> std::ops::Deref for WithSheet<T> {
    type Target = T;
    fn deref(&self) -> &T {
        &self.request
    }
}

/// The names of [`SheetView`]'s fields, as they appear among a tool's arguments.
const SHEET_FIELDS: [&str; 3] = ["crop", "zoom", "draw"];

impl<'de, T: DeserializeOwned> Deserialize<'de> for WithSheet<T> {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error as _;
        let mut fields = Map::<String, Value>::deserialize(d)?;
        let mut view = Map::new();
        for name in SHEET_FIELDS {
            if let Some(v) = fields.remove(name) {
                view.insert(name.to_string(), v);
            }
        }
        let sheet = SheetView::deserialize(Value::Object(view)).map_err(D::Error::custom)?;
        let request = T::deserialize(Value::Object(fields)).map_err(D::Error::custom)?;
        Ok(WithSheet { request, sheet })
    }
}

impl<T: Serialize> Serialize for WithSheet<T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        use serde::ser::Error as _;
        let as_object = |v: Value, what: &str| match v {
            Value::Object(m) => Ok(m),
            other => Err(S::Error::custom(format!(
                "{what} must serialise as an object of fields, not {other}"
            ))),
        };
        let mut fields = as_object(
            serde_json::to_value(&self.request).map_err(S::Error::custom)?,
            "a search request",
        )?;
        let view = as_object(
            serde_json::to_value(self.sheet).map_err(S::Error::custom)?,
            "a sheet view",
        )?;
        for (name, v) in view {
            if fields.insert(name.clone(), v).is_some() {
                return Err(S::Error::custom(format!(
                    "the request has a field `{name}` of its own beside the sheet view's"
                )));
            }
        }
        fields.serialize(s)
    }
}

impl<T: JsonSchema> JsonSchema for WithSheet<T> {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        format!("{}WithSheet", T::schema_name()).into()
    }

    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let mut schema = T::json_schema(generator);
        let view = SheetView::json_schema(generator);
        if let Some(Value::Object(view_properties)) = view.get("properties") {
            if let Value::Object(properties) = schema
                .ensure_object()
                .entry("properties")
                .or_insert_with(|| Value::Object(Map::new()))
            {
                properties.extend(view_properties.clone());
            }
        }
        schema
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rank_ranges_parse_print_and_refuse_what_is_no_range() {
        let r: RankRange = " 6 - 11".parse().expect("range");
        assert_eq!(r, RankRange { from: 6, to: 11 });
        assert_eq!(r.to_string(), "6-11");
        assert!(r.contains(6) && r.contains(11) && !r.contains(5) && !r.contains(12));
        assert_eq!("#7".parse::<RankRange>(), Ok(RankRange { from: 7, to: 7 }));
        assert_eq!(
            "#6–#17".parse::<RankRange>(),
            Ok(RankRange { from: 6, to: 17 })
        );
        assert_eq!(RankRange { from: 7, to: 7 }.to_string(), "7");
        for bad in ["", "a", "3-", "11-6", "-2", "0-100", "1,2"] {
            assert!(bad.parse::<RankRange>().is_err(), "{bad}");
        }
        assert_eq!(
            serde_json::from_value::<RankRange>(serde_json::json!(7)).expect("number"),
            RankRange { from: 7, to: 7 }
        );
        assert!(serde_json::from_value::<RankRange>(serde_json::json!([1, 2])).is_err());
    }

    #[derive(Debug, PartialEq, Deserialize, Serialize, JsonSchema)]
    #[serde(deny_unknown_fields)]
    struct Request {
        /// Which frames.
        frames: String,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        evals: Option<u64>,
    }

    #[test]
    fn a_request_with_a_sheet_is_one_flat_object_refusing_unknown_fields() {
        let a: WithSheet<Request> = serde_json::from_value(
            serde_json::json!({"frames": "1", "zoom": 4.0, "crop": "1,2,30,40"}),
        )
        .expect("parse");
        assert_eq!(a.frames, "1");
        assert_eq!(a.sheet.zoom, Some(4.0));
        assert_eq!(
            a.sheet.crop,
            Some(Crop::Box {
                x0: 1,
                y0: 2,
                x1: 30,
                y1: 40
            })
        );
        let back = serde_json::to_value(&a).expect("serialise");
        assert_eq!(
            back,
            serde_json::json!({"frames": "1", "zoom": 4.0, "crop": "1,2,30,40"})
        );
        let drawn: WithSheet<Request> =
            serde_json::from_value(serde_json::json!({"frames": "1", "draw": "6-11"}))
                .expect("parse");
        assert_eq!(drawn.sheet.draw, Some(RankRange { from: 6, to: 11 }));
        assert_eq!(
            serde_json::to_value(&drawn).expect("serialise"),
            serde_json::json!({"frames": "1", "draw": "6-11"})
        );
        let plain: WithSheet<Request> =
            serde_json::from_value(serde_json::json!({"frames": "2"})).expect("parse");
        assert_eq!(plain.sheet, SheetView::default());
        assert_eq!(
            serde_json::to_value(&plain).expect("serialise"),
            serde_json::json!({"frames": "2"})
        );
        let unknown = serde_json::from_value::<WithSheet<Request>>(
            serde_json::json!({"frames": "1", "zooom": 2.0}),
        )
        .expect_err("unknown field");
        assert!(unknown.to_string().contains("zooom"), "{unknown}");
        let bad_crop = serde_json::from_value::<WithSheet<Request>>(
            serde_json::json!({"frames": "1", "crop": "3,3,1,1"}),
        )
        .expect_err("bad crop");
        assert!(
            bad_crop.to_string().contains("x1 must exceed x0"),
            "{bad_crop}"
        );
    }

    #[test]
    fn the_schema_lists_the_sheet_view_beside_the_request_fields() {
        let schema =
            serde_json::to_value(schemars::schema_for!(WithSheet<Request>)).expect("schema");
        let props = schema["properties"].as_object().expect("properties");
        let mut names: Vec<&str> = props.keys().map(String::as_str).collect();
        names.sort_unstable();
        assert_eq!(names, ["crop", "draw", "evals", "frames", "zoom"]);
        assert_eq!(props["zoom"]["maximum"], 8.0);
        assert_eq!(props["zoom"]["minimum"], 1.0);
        assert!(props["crop"]["description"]
            .as_str()
            .is_some_and(|d| d.contains("candidate sheet")));
        assert_eq!(schema["additionalProperties"], false);
        assert_eq!(schema["required"], serde_json::json!(["frames"]));
    }

    #[test]
    fn zoom_keeps_its_bounds() {
        let view = |zoom: Option<f64>| SheetView {
            crop: None,
            zoom,
            draw: None,
        };
        assert_eq!(view(None).zoom(), Ok(1.0));
        assert_eq!(view(Some(8.0)).zoom(), Ok(8.0));
        for bad in [0.5, 9.0, f64::NAN] {
            let e = view(Some(bad)).zoom().expect_err("refused");
            assert!(e.contains("from 1 to 8"), "{e}");
        }
    }
}
