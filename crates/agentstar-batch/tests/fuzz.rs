//! The batch files and the scheduler's answers, mutated: `batch.json` (and a job's
//! `job.json`), a job's `record.json`, and what `sbatch`, `squeue` and `sacct` print. Every
//! reader answers every input (a value or an error), never panics or hangs; a manifest that
//! parses is checked as `batch` checks one it reads. Seeds in `fuzz/corpus/batch_*` and
//! `fuzz/corpus/slurm_output` (written by `agentstar batch plan` and `batch local`).

#[path = "../../../fuzz/harness.rs"]
mod harness;

use agentstar_batch::record::JobRecord;
use agentstar_batch::slurm::{parse_sacct, parse_sbatch, parse_squeue};
use agentstar_batch::Manifest;

#[test]
fn batch_files_and_scheduler_output_never_panic_the_readers() {
    harness::fuzz(
        vec![
            (
                "batch_manifest",
                Box::new(|b: &[u8]| {
                    if let Ok(m) = serde_json::from_slice::<Manifest>(b) {
                        let _ = m.check();
                        for j in &m.jobs {
                            let _ = m.job(&j.name);
                        }
                    }
                }) as harness::Run,
            ),
            (
                "batch_record",
                Box::new(|b: &[u8]| {
                    if let Ok(r) = serde_json::from_slice::<JobRecord>(b) {
                        let _ = (r.finished(), r.total_wall_s(), r.last(), r.outputs());
                    }
                }),
            ),
            (
                "slurm_output",
                Box::new(|b: &[u8]| {
                    let text = String::from_utf8_lossy(b);
                    let _ = parse_sbatch(&text);
                    let _ = parse_squeue(&text);
                    let _ = parse_sacct(&text);
                }),
            ),
        ],
        6,
    );
}
