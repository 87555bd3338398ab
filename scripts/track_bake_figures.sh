#!/usr/bin/env bash
# Issue 33's done-when figures for `track` with a model that carries its appearance and for
# `track --bake`: the hard suite's labelcan (capture seed 300) and printed mug (seed 302),
# rebuilt with `synth` exactly as `bench --suite hard` makes them, the true model given
#   (a) as a textured GLB, (b) as an OBJ + MTL with map_Kd (`synth --mesh-models`),
#   (c) uncoloured (plain.glb), without and with --bake,
# each tracked with every tracker seed in $SEEDS. Prints one row per run: the mean, median
# and largest rotation error against the true poses (degrees, per keyframe, in the capture's
# cameras), the same about the body's axis alone with up and down not told apart (what an
# outline symmetric about its axis and upside down can fix: the can's), the rotation error
# with a half-turn about the model's x axis not told apart (what the printed mug's outline,
# the same turned half way about its handle's axis, can fix), and what --bake did.
#
#   scripts/track_bake_figures.sh [OUT]
#   (OBJECTS="highmug:310" for the mug with its handle high, whose outline tells top from
#    bottom where the handle is in view: in no suite, made for this figure)
#   (AGENTSTAR=path/to/agentstar, SEEDS="17 18 19", OBJECTS="labelcan:300 printmug:302",
#    CASES="textured.glb,textured.obj,plain.glb,plain.glb --bake", BETWEEN=9 for the
#    captures with 9 in-between frames a keyframe step, as `bench --between 9` makes them)
#
# Use a release build (`cargo build --release -p agentstar`); a debug build takes hours.
set -euo pipefail
BIN=${AGENTSTAR:-target/release/agentstar}
OUT=${1:-/tmp/agentstar-track-bake-figures}
SEEDS=${SEEDS:-"17 18 19"}
OBJECTS=${OBJECTS:-"labelcan:300 printmug:302"}
CASES=${CASES:-"textured.glb,textured.obj,plain.glb,plain.glb --bake"}
BETWEEN=${BETWEEN:-}
mkdir -p "$OUT"
date -u +"started %Y-%m-%dT%H:%M:%SZ on $(nproc) threads, load $(cut -d' ' -f1-3 /proc/loadavg)" >&2

# The hard suite's captures (agentstar-bench's hard_sequence): 20 keyframes at 640×480,
# hard-held motion, hands up to 60%, 2 px mask noise, the principal point off centre.
capture() { # object seed
    local dir="$OUT/$1-s$2${BETWEEN:+-between$BETWEEN}"
    [ -f "$dir/capture.json" ] || "$BIN" synth "$dir" --object "$1" --motion hard-held \
        --frames 20 --size 640x480 --seed "$2" --mask-noise 2 --no-depth \
        --principal-point 358,218 --hand-coverage 0.6 --mesh-models \
        ${BETWEEN:+--between "$BETWEEN"} >/dev/null
    echo "$dir"
}

errors() { # truth.json tracked.json report.json label
    python3 - "$@" <<'PY'
import json, math, sys
truth, tracked, report, label = sys.argv[1:5]
t = json.load(open(truth))["frames"]
p = json.load(open(tracked))["frames"]
def rot(q):
    w, x, y, z = q
    return [[1-2*(y*y+z*z), 2*(x*y-w*z), 2*(x*z+w*y)],
            [2*(x*y+w*z), 1-2*(x*x+z*z), 2*(y*z-w*x)],
            [2*(x*z-w*y), 2*(y*z+w*x), 1-2*(x*x+y*y)]]
def angle(qa, qb):
    d = abs(sum(a*b for a, b in zip(qa, qb))) / math.sqrt(sum(a*a for a in qa) * sum(b*b for b in qb))
    return math.degrees(2*math.acos(min(1.0, d)))
full, axis, flip = [], [], []
for name, e in t.items():
    if name not in p:
        continue  # an in-between frame: keyframes are scored
    qa = e["object_pose"]["quaternion"]
    qb = p[name]["object_pose"]["quaternion"]
    full.append(angle(qa, qb))
    w, x, y, z = qb  # the tracked pose turned half way about the model's x axis (the handle's)
    flip.append(min(angle(qa, qb), angle(qa, [-x, w, z, -y])))
    za = [row[2] for row in rot(qa)]
    zb = [row[2] for row in rot(qb)]
    na = math.sqrt(sum(v*v for v in za)); nb = math.sqrt(sum(v*v for v in zb))
    c = sum(a*b for a, b in zip(za, zb)) / (na*nb)
    a = math.degrees(math.acos(max(-1.0, min(1.0, c))))
    axis.append(min(a, 180 - a))
def stats(v):
    s = sorted(v)
    return f"{sum(v)/len(v):6.2f} {s[len(s)//2]:6.2f} {s[-1]:6.2f}"
r = json.load(open(report))
b = r.get("bake")
if b:
    settled = sum(1 for f in b["frames"] if f["settled"])
    what = f"bake {b['outcome']}: {settled}/{len(b['frames'])} settled"
    if b["seen_texels"] is not None:
        what += f", {b['seen_texels']}/{b['surface_texels']} texels seen"
    if b["outcome"] == "used":
        what += f", {len(b['basin_moves'])} frame(s) moved"
    if b["disagreeing"]:
        what += f", disagreeing {','.join(b['disagreeing'])}"
else:
    what = "-"
print(f"{label:<34} {stats(full)}   {stats(axis)}   {stats(flip)}   {r['seconds']:6.1f}  {what}")
PY
}

echo "run                                 rotation mean/median/max (deg)   axis up-down-reduced mean/median/max   half-turn-about-x-reduced   s   bake"
IFS=',' read -r -a cases <<<"$CASES"
for spec in $OBJECTS; do
    object=${spec%%:*}
    cap=$(capture "$object" "${spec##*:}")
    for seed in $SEEDS; do
        for case in "${cases[@]}"; do
            model=${case%% *}
            flags=""
            [ "$case" != "$model" ] && flags=${case#* }
            run="$OUT/runs/$object-$seed-${model%%.*}-${model##*.}${flags:+-bake}${BETWEEN:+-between$BETWEEN}"
            mkdir -p "$run"
            # shellcheck disable=SC2086
            "$BIN" track "$cap" --model "$cap/model/$model" --scale-from "$cap/model/pose.json" \
                --seed "$seed" --out "$run/pose.json" --json $flags >"$run/report.json" 2>"$run/log.txt"
            errors "$cap/model/pose.json" "$run/pose.json" "$run/report.json" "$object s$seed $case"
        done
    done
done
date -u +"ended %Y-%m-%dT%H:%M:%SZ, load $(cut -d' ' -f1-3 /proc/loadavg)" >&2
