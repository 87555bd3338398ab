//! The model a search runs on. A render's cost grows with the model's triangles (every
//! vertex is projected and every edge tested for the outline), so a dense model (a scan, a
//! finely tessellated lathe, an agent's 20k-triangle script) would make tracking minutes
//! long. The tracker therefore searches on a stand-in whose parts are simplified
//! ([`agentstar_geom::simplify`]) under a bound of a fraction of a pixel at the keyframes'
//! resolution, and polishes every pose on the model itself at the end
//! ([`crate::tracker`]); the scores it reports are the model's.

use agentstar_geom::simplify::{simplified_model, SimplifyReport};
use agentstar_geom::ObjectModel;
use agentstar_render::BitMask;

/// Models with fewer triangles than this are searched as they are.
pub const STANDIN_MIN_TRIANGLES: usize = 2000;
/// About how many triangles the stand-in keeps (the deviation bound wins over the count).
pub const STANDIN_TRIANGLES: usize = 600;
/// How far the stand-in's surface may move from the model's, in pixels at the scale of the
/// largest keyframe mask. A pixel: the masks' own boundaries are off by 1–2 px (the band
/// score leaves ±2 px out), so the basin a search lands in does not depend on it, and the
/// polish on the model takes out what it shifts. Measured on the hard suite's shears
/// (3,180 triangles, two tori): 0.25 px left 3,180, 1 px gives 608 and 53 s -> 23 s with
/// EPE 0.79 -> 0.58 cm.
pub const STANDIN_DEVIATION_PX: f64 = 1.0;
/// Holes whose rims are shorter than this (pixels at the same scale) are closed on the
/// stand-in: a scan's or a broken export's pinholes would lock their rims and keep it dense.
/// Such a hole changes the silhouette only where it lies on the outline, and by at most the
/// area its rim encloses: L²/4π, 46 px² here (0.15% of a round mask 200 px across).
pub const STANDIN_HOLE_RIM_PX: f64 = 24.0;

/// A simplified model to search on, with what simplification did.
#[derive(Debug, Clone)]
pub struct StandIn {
    pub model: ObjectModel,
    pub report: SimplifyReport,
    /// The simplifier's largest deviation, in pixels of the largest mask.
    pub deviation_px: f64,
}

impl StandIn {
    /// One line for the tracker's log.
    pub fn describe(&self) -> String {
        let holes = match self.report.holes_closed {
            0 => String::new(),
            n => format!(", {n} hole(s) under {STANDIN_HOLE_RIM_PX} px of rim closed"),
        };
        format!(
            "searching on a stand-in of the model: {} → {} triangles (surface within {:.2} px at the largest mask's scale{holes}); poses polished on the model at the end",
            self.report.triangles_before, self.report.triangles_after, self.deviation_px
        )
    }
}

/// The stand-in of `model` for keyframes whose object masks are `masks`, or `None` when the
/// model is small enough to search as it is, no mask holds a pixel, or simplification does
/// not halve its triangles.
pub fn stand_in<'m>(
    model: &ObjectModel,
    masks: impl IntoIterator<Item = &'m BitMask>,
) -> Option<StandIn> {
    if model.triangle_count() < STANDIN_MIN_TRIANGLES {
        return None;
    }
    // Model units per pixel where the object looks largest: its bounding diagonal over the
    // largest mask's. A mask smaller than the object's projection (hands, foreshortening)
    // only makes the bound finer.
    let mask_diagonal_px = masks
        .into_iter()
        .filter_map(|m| m.bbox())
        .map(|(x0, y0, x1, y1)| {
            let (w, h) = ((x1 - x0 + 1) as f64, (y1 - y0 + 1) as f64);
            w.hypot(h)
        })
        .fold(0.0f64, f64::max);
    let model_diagonal = model
        .posed_bounds(&model.tree.rest_states())
        .extent()
        .norm();
    if !(mask_diagonal_px >= 1.0 && model_diagonal > 0.0) {
        return None;
    }
    let units_per_px = model_diagonal / mask_diagonal_px;
    let (simple, report) = simplified_model(
        model,
        STANDIN_DEVIATION_PX * units_per_px,
        STANDIN_TRIANGLES,
        STANDIN_HOLE_RIM_PX * units_per_px,
    );
    if report.triangles_after * 2 > report.triangles_before {
        return None;
    }
    Some(StandIn {
        model: simple,
        deviation_px: report.deviation / units_per_px,
        report,
    })
}
