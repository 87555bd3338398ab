//! The `bake` tool: the model's colours gathered from the keyframes at the committed poses
//! (`agentstar bake`), stored beside the model in the run, which every later tool then
//! draws, scores and tracks with.

use super::*;
use agentstar_reports::BakeReport;
use agentstar_requests::{BakeArgs, SessionArgs};

#[derive(Debug, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BakeToolArgs {
    #[schemars(description = FRAMES)]
    pub frames: Option<String>,
    /// Store the bake although some frames disagree with the others (default false: such a
    /// bake is refused, naming the frames; check their poses first).
    pub force: Option<bool>,
    /// The model file to bake, inside the run directory (default: the run's scene script).
    #[schemars(length(min = 1, max = 4096))]
    pub model: Option<String>,
}

tool!(Bake, "bake", Shape, Scene, BakeToolArgs,
    "Bake the model's print from the video: each keyframe's colours (inside its object mask, outside the hands) are gathered onto the model's surface at the committed poses, weighted by how squarely the surface faces the camera and how far from the mask's outline the pixel is, into a texture atlas stored beside the model (`scene.bake.json`); every later tool (render, score, track, the searches) then uses these colours like a printed model's. Texels no frame saw keep the part's colour. Refused, naming them, when some frames disagree with the rest (their poses put the colours elsewhere: a twin, a wrong pose) — baked from wrong poses the error is locked into the colours. Bake after the poses are right where the shape alone decides (a mug's handle in view); an edit that changes the shape makes the bake stale (ignored, with a warning) until you bake again. Baking cannot break a symmetry every frame shares: a plain can is up-down ambiguous in all of them.",
    |tb, a, step| tb.bake(&a, step));

impl Toolbox {
    /// The model file `path` names, which must lie inside the run directory (a bake is
    /// written beside it).
    fn model_in_run(&self, path: &str) -> std::result::Result<PathBuf, String> {
        let resolved = self.confine(path)?;
        let run = self
            .run
            .dir
            .canonicalize()
            .map_err(|e| format!("the run directory {}: {e}", self.run.dir.display()))?;
        if !resolved.starts_with(&run) {
            return Err(format!(
                "`{path}` is outside the run directory ({}); a bake is written beside its model, so the model must be in the run",
                self.run.dir.display()
            ));
        }
        if !resolved.is_file() {
            return Err(format!("`{path}` is not a model file"));
        }
        Ok(resolved)
    }

    /// `bake`: `agentstar bake --json` on the run's capture and poses.
    pub(super) fn bake(&self, a: &BakeToolArgs, _step: u64) -> Result<ToolOutput> {
        let model = match &a.model {
            None => self.run.scene.clone(),
            Some(p) => match self.model_in_run(p) {
                Ok(m) => m,
                Err(e) => return Ok(ToolOutput::error(e)),
            },
        };
        let session = SessionArgs {
            capture: self.run.capture.clone(),
            model,
            poses: self.run.poses.clone(),
        };
        let request = BakeArgs {
            frames: a.frames.clone(),
            force: a.force.unwrap_or(false),
        };
        #[derive(serde::Serialize)]
        struct Json {
            json: bool,
        }
        let call = Invocation::new(&["bake"])
            .with(&session)?
            .with(&request)?
            .with(&Json { json: true })?;
        let (ok, stdout, stderr) = self.exec(call.args())?;
        let report: Option<BakeReport> = serde_json::from_str(&stdout).ok();
        if !ok {
            return Ok(ToolOutput::error(failure_text(&stderr)));
        }
        let Some(report) = report else {
            return Ok(ToolOutput::error(format!(
                "bake printed no bake report: {}",
                failure_text(&stderr)
            )));
        };
        let mut text = format!(
            "bake: {} of {} texels seen ({:.1}%) from {} frame(s); colour spread {} over {} texels seen twice or more; pose version {}",
            report.seen_texels,
            report.surface_texels,
            100.0 * report.seen_fraction,
            report.frames.len(),
            report
                .spread
                .map_or("none".into(), |s| format!("{s:.1} (8-bit units)")),
            report.multi_view_texels,
            report
                .pose_version
                .map_or("none".into(), |v| v.to_string()),
        );
        if let Some(f) = &report.bake_file {
            text.push_str(&format!(
                "\nwrote {}: render, score, track and the searches now use the baked colours",
                f.display()
            ));
        }
        if report.forced {
            text.push_str(&format!(
                "\nstored with --force although {} disagree",
                report.disagreeing.join(", ")
            ));
        }
        if !report.unposed.is_empty() {
            text.push_str(&format!(
                "\nleft out (no written pose): {}",
                report.unposed.join(", ")
            ));
        }
        let mut o = ToolOutput {
            text,
            structured: serde_json::to_value(&report).ok(),
            ..Default::default()
        };
        o.scores
            .insert("seen_fraction".into(), report.seen_fraction);
        Ok(o)
    }
}
