//! `agentstar check MODEL`: build a scene script (or load a URDF or mesh) and report what it
//! holds: parts, joints, the canonical-frame measurement and warnings.

use crate::common::print_json;
use agentstar_data::scenefile::load_model;
use agentstar_reports::{CheckCanonical, CheckPart, CheckReport};
use anyhow::Result;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(clap::Args)]
#[command(after_help = "Example:\n  agentstar check run/scene.rhai")]
pub struct Args {
    /// A scene script (.rhai), URDF or mesh file.
    model: PathBuf,
    /// Print the result as JSON on stdout.
    #[arg(long)]
    json: bool,
}

pub fn run(a: Args) -> Result<ExitCode> {
    let m = load_model(&a.model)?;
    let model = &m.model;
    let r = model.canonical_report();
    let parts: Vec<_> = model
        .parts
        .iter()
        .map(|p| {
            let b = p.mesh.bounds();
            CheckPart {
                name: p.name.clone(),
                triangles: p.mesh.triangles.len(),
                watertight: p.watertight,
                volume: p.watertight.then(|| p.mesh.volume()),
                bbox_min: b.min.coords.into(),
                bbox_max: b.max.coords.into(),
                color: p.color,
            }
        })
        .collect();
    let joints: Vec<_> = model
        .tree
        .joints()
        .iter()
        .map(agentstar_data::posefile::joint_json)
        .collect();
    if a.json {
        print_json(&CheckReport {
            model: a.model.clone(),
            parts,
            joints,
            canonical: CheckCanonical {
                bbox_min: r.bbox_min,
                bbox_max: r.bbox_max,
                extent: r.extent,
                center: r.center,
                longest_side: r.longest_side,
                triangles: r.triangle_count,
            },
            warnings: m.warnings.clone(),
            printed: m.printed.clone(),
        })?;
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "{}: {} part(s), {} joint(s), {} triangles",
        a.model.display(),
        model.parts.len(),
        model.tree.joints().len(),
        r.triangle_count
    );
    println!(
        "canonical frame: extent [{:.3}, {:.3}, {:.3}], longest side {:.3}, centre ({:.3}, {:.3}, {:.3})",
        r.extent[0], r.extent[1], r.extent[2], r.longest_side, r.center[0], r.center[1], r.center[2]
    );
    for p in &model.parts {
        println!(
            "  part {:<16} {:>7} triangles{}",
            p.name,
            p.mesh.triangles.len(),
            if p.watertight {
                ""
            } else {
                "  (not watertight)"
            }
        );
    }
    for j in model.tree.joints() {
        let limit = j
            .limit
            .map(|(lo, hi)| format!(" limit [{lo}, {hi}]"))
            .unwrap_or_default();
        println!(
            "  joint {:<15} {} child {:?} origin {:?} axis {:?}{limit}{}",
            j.name,
            j.kind.as_str(),
            j.child,
            j.origin.as_slice(),
            j.axis.as_slice(),
            j.parent
                .as_ref()
                .map(|p| format!(" parent {p}"))
                .unwrap_or_default()
        );
    }
    for w in &m.warnings {
        println!("warning: {w}");
    }
    for line in &m.printed {
        println!("print: {line}");
    }
    Ok(ExitCode::SUCCESS)
}
