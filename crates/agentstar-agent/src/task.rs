//! The task document the agent reads (`TASK.md`), and the short instructions an MCP client
//! shows its model.

/// The gate on every keyframe's visible-region IoU (defined once, in `reports`).
pub use crate::reports::GATE_IOU;

const TASK: &str = r#"# Your task

You are given a video of an object: keyframes, a mask of the object in each (hands cut out
and marked separately), and the camera of each keyframe. Build a model of the object **as
code** and find its pose in every keyframe, so that the model drawn into each keyframe covers
the object's mask.

- The model is `scene.rhai`: named parts built from primitives, joined by revolute or
  prismatic joints with limits (the API is at the end of this document). Real sizes come
  from one shared scale (metres per model unit) in `pose.json`.
- A pose is the object's rotation and position in the camera, plus the state of every joint.
  `pose.json` holds one per keyframe. You never type pose numbers: you name a search region
  and pick among the candidates the search returns.

## Conventions

- Cameras are OpenCV: +X right, +Y down, +Z forward. The model's canonical frame is +Z up,
  centred at the origin, longest side about 1; joints rest at 0.
- Camera-frame increments: `roll` (about the view axis), `yaw`, `pitch` (degrees, about the
  object's centre), `dpx`, `dpy` (fractions of the object's image size), `tz` (fraction of its
  depth). Object-frame rotations: `rx`, `ry`, `rz`, and `flip:x|y|z` (180°). Joint states:
  degrees (revolute) or model units (prismatic), absolute.
- Scores: IoU of the rendered silhouette with the mask, counting only pixels outside the hand
  masks ("visible"). The gate is 0.98 on every keyframe.

## How to work

Alternate two kinds of steps; **each step changes the shape or the poses, never both**.

1. **Shape step.** Read the keyframes and the comparisons, then rewrite `scene.rhai` with
   `scene_write` (the whole script). It is checked before it replaces the current one: on a
   syntax or geometry error you get the message and nothing changes. Check the result with
   `turntable` in every joint state: the 3-D shape must be coherent from every side, not only
   from the camera.
2. **Pose step.** Pick the worst keyframes (`score`, `temporal`), name a bounded region with
   `sweep` (camera-frame ranges and joint ranges, e.g. `yaw:-30,30;pitch:-20,20;hinge:0,90`)
   or the object-frame verbs (`osweep`, `oapply` with `flips` for near-symmetric objects,
   `oapply_all` when the model is built the wrong way round), look at the candidate sheet, and
   commit the candidate you believe with `pose_commit`. A high IoU on a wrong pose is still
   wrong: a mirror or 180° flip of a symmetric-looking object can score well. `track` runs the
   automatic tracker over every keyframe; use it once the shape is right to start the poses.
3. Keep notes with `notes`: what the object is, which parts move, what you ruled out. Notes
   survive when older images leave your context.

## Reading the images

- **compare**: green = model and mask agree, red = mask not covered (model too small or
  misplaced there), blue = model outside the mask (too big or misplaced), grey = hand
  (ignored), white = background.
- **overlay**: the shaded model over the frame, part colours as in the scene.
- **candidate sheet** (sweeps): one tile per candidate, ranked, each with its scores and the
  order that produced it.
- **turntable**: eight views around the model per joint state; look for parts floating,
  intersecting, or missing from the back.
- **temporal plot**: rotation and translation from keyframe to keyframe after removing the
  camera's motion; a spike is either real fast motion or a wrong pose (usually a flip).

## Gates before you finish

Call `finish` only when all of these hold; it checks them and tells you what is missing:

1. Every keyframe's visible IoU ≥ 0.98, or a written reason for each keyframe that cannot
   reach it (heavy occlusion, a bad mask), given to `finish`.
2. `turntable` was looked at after the last shape change, and the shape is coherent in every
   joint state.
3. `temporal` was looked at after the last pose change, and every large step is either
   confirmed in the frames or fixed.

## Budgets

A run has limits on steps, wall time and tokens; the harness tells you what is left. Spend
early steps on the shape (it limits every pose), then poses, then the gates. Do not repeat a
search that failed: change the region or the shape.

"#;

/// The task document: how to work, the gates, and the scene API with a worked example.
pub fn task_document() -> String {
    let mut s = String::from(TASK);
    s.push_str("# The scene API\n\n");
    let scene = include_str!("../../../docs/scene.md");
    // The scene document's own title is replaced by the heading above.
    let body = scene
        .split_once('\n')
        .map(|(_, rest)| rest)
        .unwrap_or(scene);
    s.push_str(body.trim_start());
    s
}

/// What an MCP client shows its model when it connects.
pub const MCP_INSTRUCTIONS: &str = "agentstar fits an object model written as code (scene.rhai) and its pose in every keyframe of a video to the object's masks. Read TASK.md in the run directory first (the tool `task` returns it): it explains the loop (each step changes the shape or the poses, never both), how to read the images, and the gates `finish` checks. Shape tools: scene_read, scene_write, scene_restore, turntable. Pose tools: track, sweep, apply, osweep, oapply, oapply_all, pose_commit, pose_history, pose_restore. Diagnostics: render, score, temporal, pose_diff, critic. Images come back inline and as files under the run's images/ directory.";

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_task_document_holds_the_gates_and_the_whole_scene_api() {
        let t = task_document();
        assert!(t.contains("0.98") && t.contains("finish"));
        assert!(t.contains("A worked articulated example"));
        assert!(t.contains("joint("));
        // Short enough to read whole: under ~5,000 words.
        assert!(
            t.split_whitespace().count() < 5000,
            "{}",
            t.split_whitespace().count()
        );
    }
}
