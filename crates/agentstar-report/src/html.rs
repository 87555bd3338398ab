//! The page: static HTML and CSS, the data as JSON, the viewer script.

use crate::svg::{line_chart, Series};
use crate::{Image, Report, THREE_JS};
use base64::Engine;
use serde_json::json;
use std::fmt::Write;

/// Escapes text for HTML content and attribute values.
pub fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&#39;"),
            _ => o.push(c),
        }
    }
    o
}

/// A frame name without its extension, for axis labels.
fn stem(name: &str) -> String {
    match name.rsplit_once('.') {
        Some((s, ext)) if !s.is_empty() && ext.len() <= 4 => s.to_string(),
        _ => name.to_string(),
    }
}

fn b64(bytes: &[u8]) -> String {
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

fn data_uri(img: &Image) -> String {
    format!("data:{};base64,{}", img.mime, b64(&img.bytes))
}

/// JSON safe to place inside a `<script>` element (`</` cannot close it).
fn script_json(v: &serde_json::Value) -> String {
    v.to_string().replace("</", "<\\/")
}

fn f32_b64(v: &[f32]) -> String {
    let mut bytes = Vec::with_capacity(v.len() * 4);
    for x in v {
        bytes.extend_from_slice(&x.to_le_bytes());
    }
    b64(&bytes)
}

fn u32_b64(v: &[u32]) -> String {
    let mut bytes = Vec::with_capacity(v.len() * 4);
    for x in v {
        bytes.extend_from_slice(&x.to_le_bytes());
    }
    b64(&bytes)
}

const CSS: &str = r#"
:root { --fg:#1d2330; --muted:#5b6475; --line:#d9dde5; --accent:#0b63ce; --bg:#f6f7f9; }
* { box-sizing: border-box; }
body { margin:0; font:14px/1.45 system-ui, -apple-system, "Segoe UI", Roboto, sans-serif; color:var(--fg); background:var(--bg); }
header { padding:18px 28px; background:#fff; border-bottom:1px solid var(--line); }
header h1 { margin:0; font-size:22px; }
header p { margin:4px 0 0; color:var(--muted); }
nav { padding:8px 28px; background:#fff; border-bottom:1px solid var(--line); position:sticky; top:0; z-index:2; }
nav a { margin-right:18px; color:var(--accent); text-decoration:none; }
section { padding:18px 28px; }
h2 { font-size:18px; margin:0 0 12px; }
table.kv { border-collapse:collapse; background:#fff; }
table.kv td { padding:4px 12px; border-bottom:1px solid var(--line); vertical-align:top; }
table.kv td:first-child { color:var(--muted); white-space:nowrap; }
.cols { display:flex; flex-wrap:wrap; gap:24px; align-items:flex-start; }
.notes { color:#8a5a00; }
.views { display:flex; flex-wrap:wrap; gap:16px; }
.view { background:#fff; border:1px solid var(--line); padding:8px; }
.view h3 { margin:0 0 6px; font-size:14px; color:var(--muted); font-weight:600; }
.camview { position:relative; line-height:0; }
.camview img, .camview canvas { display:block; }
.camview canvas { position:absolute; left:0; top:0; }
#orbit { cursor:grab; touch-action:none; }
.controls { margin-top:10px; display:flex; gap:12px; align-items:center; }
.controls input[type=range] { width:320px; }
#viewer-message { color:#a00; }
.charts { display:flex; flex-wrap:wrap; gap:16px; }
svg.chart { width:640px; max-width:100%; background:#fff; border:1px solid var(--line); }
svg.chart .chart-title { font-weight:600; font-size:13px; fill:var(--fg); }
svg.chart .tick { font-size:11px; fill:var(--muted); }
.grid { display:grid; grid-template-columns:repeat(auto-fill, minmax(260px, 1fr)); gap:12px; }
figure { margin:0; background:#fff; border:1px solid var(--line); padding:6px; }
figure img { width:100%; display:block; image-rendering:auto; }
figcaption { font-size:12px; color:var(--muted); padding-top:4px; }
.bad { color:#b00020; font-weight:600; }
.good { color:#137333; }
ol.timeline { list-style:none; margin:0; padding:0; border-left:3px solid var(--line); }
ol.timeline li { position:relative; margin:0 0 14px 0; padding:8px 12px 8px 18px; background:#fff; border:1px solid var(--line); margin-left:14px; }
ol.timeline li::before { content:""; position:absolute; left:-24px; top:14px; width:11px; height:11px; border-radius:50%; background:var(--accent); }
ol.timeline li.kind-shape::before { background:#8e44ad; }
ol.timeline li.kind-pose::before { background:#0b63ce; }
ol.timeline li.kind-diagnostic::before { background:#e67e22; }
.step-head { display:flex; gap:10px; align-items:baseline; flex-wrap:wrap; }
.badge { font-size:11px; padding:1px 6px; border-radius:8px; background:#eef1f6; color:var(--muted); }
.tool { font-family:ui-monospace, SFMono-Regular, Menlo, monospace; font-weight:600; }
.thumbs { display:flex; gap:8px; flex-wrap:wrap; margin-top:6px; }
.thumbs figure { width:200px; }
footer { padding:18px 28px; color:var(--muted); }
"#;

/// The viewer: loads three.js from the inlined source, builds the parts, animates them
/// through the keyframes in the camera view (over the frame) and in an orbit view.
const VIEWER_JS: &str = r#"
const errors = [];
const consoleError = console.error.bind(console);
console.error = (...a) => { errors.push(a.map(String).join(' ')); consoleError(...a); };
window.addEventListener('error', (e) => errors.push(String(e.message || e)));
window.addEventListener('unhandledrejection', (e) => errors.push(String(e.reason)));
function publish() {
  document.body.dataset.errors = String(errors.length);
  document.body.dataset.errorText = errors.join(' | ').slice(0, 2000);
}
function decode(b64, Type) {
  const s = atob(b64);
  const bytes = new Uint8Array(s.length);
  for (let i = 0; i < s.length; i++) bytes[i] = s.charCodeAt(i);
  return new Type(bytes.buffer);
}
function coveredPixels(gl, w, h, background) {
  const px = new Uint8Array(w * h * 4);
  gl.readPixels(0, 0, w, h, gl.RGBA, gl.UNSIGNED_BYTE, px);
  let n = 0;
  for (let i = 0; i < px.length; i += 4) {
    if (background === null ? px[i + 3] > 0
        : Math.abs(px[i] - background[0]) + Math.abs(px[i + 1] - background[1]) + Math.abs(px[i + 2] - background[2]) > 6) n++;
  }
  return n;
}
async function main() {
  const data = JSON.parse(document.getElementById('report-data').textContent);
  const frames = data.frames;
  if (!frames.length || !data.parts.length) { document.body.dataset.viewer = 'empty'; return; }
  const src = document.getElementById('three-src').textContent;
  const url = URL.createObjectURL(new Blob([src], { type: 'text/javascript' }));
  const THREE = await import(url);
  URL.revokeObjectURL(url);
  const scene = new THREE.Scene();
  scene.add(new THREE.HemisphereLight(0xffffff, 0x667788, 2.2));
  const sun = new THREE.DirectionalLight(0xffffff, 1.4);
  sun.position.set(1, -2, -3);
  scene.add(sun);
  // Colours are display (sRGB) values; three.js works in linear space.
  const srgb = (c) => new THREE.Color().setRGB(c[0], c[1], c[2], THREE.SRGBColorSpace);
  const wraps = { 10497: THREE.RepeatWrapping, 33648: THREE.MirroredRepeatWrapping, 33071: THREE.ClampToEdgeWrapping };
  const surfaceMesh = (p) => {
    // Textures and vertex colours: one vertex per triangle corner, a group per material.
    const s = p.surface, pos = decode(p.positions, Float32Array), tri = decode(p.triangles, Uint32Array);
    const order = decode(s.order, Uint32Array), cols = decode(s.colors, Float32Array), uvs = decode(s.uvs, Float32Array);
    const corner = new Float32Array(order.length * 9), lin = new Float32Array(cols.length);
    order.forEach((t, i) => { for (let k = 0; k < 3; k++) for (let d = 0; d < 3; d++) corner[i * 9 + k * 3 + d] = pos[tri[t * 3 + k] * 3 + d]; });
    const c = new THREE.Color();
    for (let i = 0; i < cols.length; i += 3) { c.setRGB(cols[i], cols[i + 1], cols[i + 2], THREE.SRGBColorSpace); lin[i] = c.r; lin[i + 1] = c.g; lin[i + 2] = c.b; }
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(corner, 3));
    g.setAttribute('color', new THREE.BufferAttribute(lin, 3));
    if (uvs.length) g.setAttribute('uv', new THREE.BufferAttribute(uvs, 2));
    let start = 0;
    s.groups.forEach(([n, mat]) => { g.addGroup(start * 3, n * 3, mat); start += n; });
    const textures = s.textures.map((t) => {
      const tex = new THREE.TextureLoader().load(t.png);
      tex.colorSpace = THREE.SRGBColorSpace; tex.flipY = false;
      tex.wrapS = wraps[t.wrap[0]] ?? THREE.RepeatWrapping; tex.wrapT = wraps[t.wrap[1]] ?? THREE.RepeatWrapping;
      return tex;
    });
    const mats = s.materials.map((m) => new THREE.MeshLambertMaterial({ color: srgb(m.color), vertexColors: true,
      map: m.texture === null ? null : textures[m.texture], transparent: true, opacity: 0.75, side: THREE.DoubleSide }));
    return [g, mats];
  };
  const parts = data.parts.map((p) => {
    let g, mat;
    if (p.surface) {
      [g, mat] = surfaceMesh(p);
    } else {
      g = new THREE.BufferGeometry();
      g.setAttribute('position', new THREE.BufferAttribute(decode(p.positions, Float32Array), 3));
      g.setIndex(new THREE.BufferAttribute(decode(p.triangles, Uint32Array), 1));
      mat = new THREE.MeshLambertMaterial({ color: srgb(p.color), transparent: true, opacity: 0.75, side: THREE.DoubleSide });
    }
    g.computeVertexNormals();
    g.computeBoundingSphere();
    const m = new THREE.Mesh(g, mat);
    m.matrixAutoUpdate = false;
    scene.add(m);
    return m;
  });
  // The camera view: OpenCV intrinsics as a projection matrix, the frame behind the canvas.
  const flip = new THREE.Matrix4().makeScale(1, -1, -1);
  const bg = document.getElementById('cam-bg');
  const camCanvas = document.getElementById('cam');
  const f0 = frames[0];
  const camW = Math.min(560, f0.size[0]);
  const camH = Math.round(camW * f0.size[1] / f0.size[0]);
  bg.width = camW; bg.height = camH;
  const camRenderer = new THREE.WebGLRenderer({ canvas: camCanvas, alpha: true, antialias: true, preserveDrawingBuffer: true });
  camRenderer.setPixelRatio(1);
  camRenderer.setSize(camW, camH);
  camRenderer.setClearColor(0x000000, 0);
  const camera = new THREE.PerspectiveCamera();
  camera.matrixAutoUpdate = false;
  const near = 0.01, far = 100;
  function setCamera(f) {
    const [fx, fy, cx, cy] = f.intrinsics, [w, h] = f.size;
    camera.projectionMatrix.set(
      2 * fx / w, 0, 1 - 2 * cx / w, 0,
      0, 2 * fy / h, 2 * cy / h - 1, 0,
      0, 0, -(far + near) / (far - near), -2 * far * near / (far - near),
      0, 0, -1, 0);
    camera.projectionMatrixInverse.copy(camera.projectionMatrix).invert();
    camera.matrix.fromArray(f.world_from_camera).multiply(flip);
    camera.matrixWorldNeedsUpdate = true;
  }
  // The orbit view: a free camera around the model, the capture's cameras as a path.
  const orbitCanvas = document.getElementById('orbit');
  const orbitRenderer = new THREE.WebGLRenderer({ canvas: orbitCanvas, antialias: true, preserveDrawingBuffer: true });
  orbitRenderer.setPixelRatio(1);
  orbitRenderer.setSize(camW, camH);
  orbitRenderer.setClearColor(0xf2f4f7, 1);
  const centre = new THREE.Vector3();
  const radius = { value: 0 };
  {
    const box = new THREE.Box3();
    frames.forEach((f) => parts.forEach((m, k) => {
      const b = new THREE.Box3().setFromBufferAttribute(m.geometry.getAttribute('position'));
      b.applyMatrix4(new THREE.Matrix4().fromArray(f.world_from_part[k]));
      box.union(b);
    }));
    box.getCenter(centre);
    radius.value = Math.max(box.getSize(new THREE.Vector3()).length(), 1e-3);
  }
  const path = new THREE.Line(
    new THREE.BufferGeometry().setFromPoints(frames.map((f) => new THREE.Vector3().setFromMatrixPosition(new THREE.Matrix4().fromArray(f.world_from_camera)))),
    new THREE.LineBasicMaterial({ color: 0x888888 }));
  const frustum = new THREE.LineSegments(new THREE.BufferGeometry(), new THREE.LineBasicMaterial({ color: 0xd35400 }));
  frustum.matrixAutoUpdate = false;
  const orbitScene = new THREE.Scene();
  const axes = new THREE.AxesHelper(radius.value * 0.3);
  axes.position.copy(centre);
  const orbitCamera = new THREE.PerspectiveCamera(40, camW / camH, radius.value * 0.01, radius.value * 100);
  const orbit = { azimuth: 0.8, elevation: 0.5, distance: radius.value * 1.8 };
  function placeOrbit() {
    const e = orbit.elevation, a = orbit.azimuth, d = orbit.distance;
    orbitCamera.up.set(0, 0, 1);
    orbitCamera.position.set(centre.x + d * Math.cos(e) * Math.cos(a), centre.y + d * Math.cos(e) * Math.sin(a), centre.z + d * Math.sin(e));
    orbitCamera.lookAt(centre);
  }
  let dragging = null;
  orbitCanvas.addEventListener('pointerdown', (e) => { dragging = [e.clientX, e.clientY]; orbitCanvas.setPointerCapture(e.pointerId); });
  orbitCanvas.addEventListener('pointerup', () => { dragging = null; });
  orbitCanvas.addEventListener('pointermove', (e) => {
    if (!dragging) return;
    orbit.azimuth -= (e.clientX - dragging[0]) * 0.01;
    orbit.elevation = Math.max(-1.5, Math.min(1.5, orbit.elevation + (e.clientY - dragging[1]) * 0.01));
    dragging = [e.clientX, e.clientY];
    draw();
  });
  orbitCanvas.addEventListener('wheel', (e) => { e.preventDefault(); orbit.distance *= Math.exp(e.deltaY * 0.001); draw(); }, { passive: false });
  let current = 0;
  function frustumPoints(f) {
    const [fx, fy, cx, cy] = f.intrinsics, [w, h] = f.size;
    const z = radius.value * 0.25;
    const c = [[0, 0], [w, 0], [w, h], [0, h]].map(([u, v]) => new THREE.Vector3((u - cx) / fx * z, (v - cy) / fy * z, z));
    const o = new THREE.Vector3();
    return [o, c[0], o, c[1], o, c[2], o, c[3], c[0], c[1], c[1], c[2], c[2], c[3], c[3], c[0]];
  }
  function draw() {
    const f = frames[current];
    parts.forEach((m, k) => { m.matrix.fromArray(f.world_from_part[k]); m.matrixWorldNeedsUpdate = true; });
    setCamera(f);
    bg.src = document.getElementById('frame-' + current).dataset.src;
    camRenderer.render(scene, camera);
    frustum.geometry.setFromPoints(frustumPoints(f));
    frustum.matrix.fromArray(f.world_from_camera);
    frustum.matrixWorldNeedsUpdate = true;
    placeOrbit();
    scene.add(path, frustum, axes);
    orbitRenderer.render(scene, orbitCamera);
    scene.remove(path, frustum, axes);
    document.getElementById('frame-label').textContent = (current + 1) + ' / ' + frames.length + '  ' + f.name +
      (data.joint_names.length ? '  ' + data.joint_names.map((n, j) => n + ' ' + f.joint_states[j].toFixed(2)).join(', ') : '');
    document.getElementById('slider').value = String(current);
  }
  const slider = document.getElementById('slider');
  slider.max = String(frames.length - 1);
  slider.addEventListener('input', () => { current = Number(slider.value); draw(); });
  let timer = null;
  const play = document.getElementById('play');
  play.addEventListener('click', () => {
    if (timer) { clearInterval(timer); timer = null; play.textContent = 'Play'; return; }
    play.textContent = 'Pause';
    timer = setInterval(() => { current = (current + 1) % frames.length; draw(); }, 600);
  });
  draw();
  document.body.dataset.camPixels = String(coveredPixels(camRenderer.getContext(), camW, camH, null));
  document.body.dataset.orbitPixels = String(coveredPixels(orbitRenderer.getContext(), camW, camH, [242, 244, 247]));
  document.body.dataset.viewer = 'ready';
}
main().catch((e) => {
  errors.push('viewer: ' + (e && e.stack ? e.stack : e));
  const m = document.getElementById('viewer-message');
  if (m) m.textContent = 'The 3-D view could not start: ' + e + ' (it needs WebGL).';
  document.body.dataset.viewer = 'failed';
}).finally(publish);
"#;

fn kv_table(rows: &[(String, String)]) -> String {
    let mut s = String::from(r#"<table class="kv">"#);
    for (k, v) in rows {
        let _ = write!(s, "<tr><td>{}</td><td>{}</td></tr>", esc(k), esc(v));
    }
    s.push_str("</table>");
    s
}

fn iou_class(v: Option<f64>, gate: f64) -> &'static str {
    match v {
        Some(v) if v >= gate => "good",
        _ => "bad",
    }
}

/// The whole page.
pub fn render_html(r: &Report) -> String {
    let mut s = String::with_capacity(THREE_JS.len() + (1 << 20));
    let _ = write!(
        s,
        r##"<!doctype html>
<html lang="en"><head><meta charset="utf-8"><meta name="viewport" content="width=device-width, initial-scale=1">
<meta name="generator" content="{gen}"><title>{t}</title><style>{CSS}</style></head>
<body data-viewer="loading" data-errors="0">
<header><h1>{t}</h1><p>Generated by {gen}. Everything on this page is inside this one file; it works offline.</p></header>
<nav><a href="#summary">Summary</a><a href="#viewer">3-D view</a><a href="#plots">Plots</a><a href="#frames">Keyframes</a><a href="#timeline">Agent steps</a></nav>
"##,
        t = esc(&r.title),
        gen = esc(&r.generator)
    );
    // Summary.
    s.push_str(r#"<section id="summary"><h2>Summary</h2><div class="cols"><div>"#);
    s.push_str(&kv_table(&r.facts));
    s.push_str("</div>");
    if !r.metrics.is_empty() {
        s.push_str("<div><h3>Against ground truth</h3>");
        s.push_str(&kv_table(&r.metrics));
        s.push_str("</div>");
    }
    s.push_str("</div>");
    for n in &r.notes {
        let _ = write!(s, r#"<p class="notes">{}</p>"#, esc(n));
    }
    s.push_str("</section>");
    // Viewer.
    let _ = write!(
        s,
        r#"<section id="viewer"><h2>3-D view</h2><div class="views">
<div class="view"><h3>From the capture's camera</h3><div class="camview"><img id="cam-bg" alt="keyframe"><canvas id="cam"></canvas></div></div>
<div class="view"><h3>Free orbit (drag to turn, wheel to zoom; the grey path is the camera)</h3><canvas id="orbit"></canvas></div></div>
<div class="controls"><button id="play" type="button">Play</button><input id="slider" type="range" min="0" max="0" value="0"><span id="frame-label"></span></div>
<p id="viewer-message"></p></section>"#
    );
    // Plots.
    let names: Vec<String> = r.frames.iter().map(|f| stem(&f.name)).collect();
    s.push_str(r#"<section id="plots"><h2>Plots</h2><div class="charts">"#);
    s.push_str(&line_chart(
        "Silhouette IoU per keyframe",
        "IoU",
        &names,
        &[
            Series {
                name: "visible (hands excluded)".into(),
                color: "#0b63ce".into(),
                values: r.frames.iter().map(|f| f.iou_visible).collect(),
            },
            Series {
                name: "raw".into(),
                color: "#9aa5b8".into(),
                values: r.frames.iter().map(|f| Some(f.iou_raw)).collect(),
            },
        ],
        Some((r.gate, &format!("gate {}", r.gate))),
    ));
    if let Some(t) = &r.temporal {
        s.push_str(&line_chart(
            &format!("Rotation step between keyframes ({} frame)", t.pose_frame),
            "degrees",
            &t.frames.iter().map(|f| stem(f)).collect::<Vec<_>>(),
            &[Series {
                name: "rotation step".into(),
                color: "#c0392b".into(),
                values: t.rot_step_deg.clone(),
            }],
            None,
        ));
        s.push_str(&line_chart(
            "Translation step between keyframes",
            "object sizes",
            &t.frames.iter().map(|f| stem(f)).collect::<Vec<_>>(),
            &[Series {
                name: "translation step".into(),
                color: "#16a085".into(),
                values: t.trans_step.clone(),
            }],
            None,
        ));
    }
    if !r.viewer.joint_names.is_empty() {
        let palette = [
            "#8e44ad", "#d35400", "#2c3e50", "#27ae60", "#c0392b", "#2980b9",
        ];
        let series: Vec<Series> = r
            .viewer
            .joint_names
            .iter()
            .enumerate()
            .map(|(j, n)| Series {
                name: n.clone(),
                color: palette[j % palette.len()].into(),
                values: r
                    .viewer
                    .frames
                    .iter()
                    .map(|f| f.joint_states.get(j).copied())
                    .collect(),
            })
            .collect();
        let vnames: Vec<String> = r.viewer.frames.iter().map(|f| stem(&f.name)).collect();
        s.push_str(&line_chart(
            "Joint states (degrees or metres)",
            "state",
            &vnames,
            &series,
            None,
        ));
    }
    s.push_str("</div>");
    if let Some(t) = &r.temporal {
        for w in &t.warnings {
            let _ = write!(s, r#"<p class="notes">{}</p>"#, esc(w));
        }
    }
    s.push_str("</section>");
    // Keyframes.
    s.push_str(r#"<section id="frames"><h2>Keyframes</h2><div class="grid">"#);
    for (i, f) in r.frames.iter().enumerate() {
        let iou = f
            .iou_visible
            .map_or("no visible mask".to_string(), |v| format!("{v:.4}"));
        let _ = write!(
            s,
            r#"<figure id="frame-{i}" data-src="{src}"><img loading="lazy" src="{ov}" alt="{n}"><figcaption>{n} · IoU visible <span class="{c}">{iou}</span> · raw {raw:.4}{facing}</figcaption></figure>"#,
            facing = f
                .facing
                .as_ref()
                .map(|l| format!(r#"<br><span class="facing">{}</span>"#, esc(l)))
                .unwrap_or_default(),
            src = data_uri(&f.frame),
            ov = data_uri(&f.overlay),
            n = esc(&f.name),
            c = iou_class(f.iou_visible, r.gate),
            raw = f.iou_raw
        );
    }
    s.push_str("</div></section>");
    // Timeline.
    s.push_str(r#"<section id="timeline"><h2>Agent steps</h2>"#);
    if r.steps.is_empty() {
        s.push_str("<p>This run has no ledger (no agent steps were recorded).</p>");
    } else {
        s.push_str(r#"<ol class="timeline">"#);
        for st in &r.steps {
            let kind: String = st
                .kind
                .chars()
                .filter(|c| c.is_ascii_alphanumeric() || *c == '-')
                .collect();
            let _ = write!(
                s,
                r#"<li class="kind-{kind}"><div class="step-head"><span class="badge">#{n}</span><span class="badge">{t:.1} s</span><span class="badge">{k}</span><span class="tool">{tool}</span></div><div>{sum}</div>"#,
                n = st.step,
                t = st.time_s,
                k = esc(&st.kind),
                tool = esc(&st.tool),
                sum = esc(&st.summary)
            );
            if !st.scores.is_empty() {
                let sc: Vec<String> = st
                    .scores
                    .iter()
                    .map(|(k, v)| format!("{} {:.4}", esc(k), v))
                    .collect();
                let _ = write!(s, r#"<div class="badge">{}</div>"#, sc.join(" · "));
            }
            if !st.images.is_empty() {
                s.push_str(r#"<div class="thumbs">"#);
                for (cap, img) in &st.images {
                    match img {
                        Some(img) => {
                            let _ = write!(
                                s,
                                r#"<figure><img loading="lazy" src="{}" alt="{c}"><figcaption>{c}</figcaption></figure>"#,
                                data_uri(img),
                                c = esc(cap)
                            );
                        }
                        None => {
                            let _ = write!(
                                s,
                                r#"<figure><figcaption class="bad">{} (missing)</figcaption></figure>"#,
                                esc(cap)
                            );
                        }
                    }
                }
                s.push_str("</div>");
            }
            s.push_str("</li>");
        }
        s.push_str("</ol>");
    }
    s.push_str("</section>");
    let _ = write!(
        s,
        r#"<footer>three.js r170 (MIT) is embedded for the 3-D view.</footer>"#
    );
    // Data and scripts.
    let data = json!({
        "parts": r.viewer.parts.iter().map(|p| {
            let mut part = json!({
                "name": p.name, "color": p.color,
                "positions": f32_b64(&p.positions), "triangles": u32_b64(&p.triangles),
            });
            if let Some(sf) = &p.surface {
                part["surface"] = json!({
                    "order": u32_b64(&sf.order),
                    "colors": f32_b64(&sf.corner_colors),
                    "uvs": f32_b64(&sf.corner_uvs),
                    "groups": sf.groups,
                    "materials": sf.materials.iter().map(|m| json!({"color": m.color, "texture": m.texture})).collect::<Vec<_>>(),
                    "textures": sf.textures.iter().map(|t| json!({"png": format!("data:image/png;base64,{}", b64(&t.png)), "wrap": t.wrap})).collect::<Vec<_>>(),
                });
            }
            part
        }).collect::<Vec<_>>(),
        "joint_names": r.viewer.joint_names,
        "frames": r.viewer.frames.iter().map(|f| json!({
            "name": f.name, "world_from_part": f.world_from_part,
            "world_from_camera": f.world_from_camera, "intrinsics": f.intrinsics,
            "size": f.size, "joint_states": f.joint_states,
        })).collect::<Vec<_>>(),
    });
    let _ = write!(
        s,
        r#"<script id="report-data" type="application/json">{}</script>
<script id="three-src" type="text/plain">{}</script>
<script type="module">{VIEWER_JS}</script>
</body></html>
"#,
        script_json(&data),
        THREE_JS.replace("</script", "<\\/script")
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn escaping_covers_markup_and_quotes() {
        assert_eq!(
            esc(r#"<a href="x">'&'</a>"#),
            "&lt;a href=&quot;x&quot;&gt;&#39;&amp;&#39;&lt;/a&gt;"
        );
        assert_eq!(
            script_json(&json!({"s": "</script>"})),
            r#"{"s":"<\/script>"}"#
        );
    }

    #[test]
    fn the_inlined_three_js_is_one_module_without_imports() {
        assert!(THREE_JS.contains("WebGLRenderer"));
        assert!(!THREE_JS.contains("</script"));
        assert!(!THREE_JS.contains("from\"./") && !THREE_JS.contains("from \"./"));
    }
}
