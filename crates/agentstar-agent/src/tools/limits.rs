//! Acknowledged joint-limit warnings: `temporal` and `turntable` take
//! `acknowledge_limits: true` to record the warnings of a joint piled at a limit that their
//! reply finds, in `RUN/.agentstar/limits_acknowledged.json` (written atomically), and later
//! replies summarise those in one line while they stay the same.

use super::*;
use agentstar_reports::limits::{AcknowledgedLimits, JointAtLimit};

impl Toolbox {
    /// Where the run keeps its acknowledged joint-limit warnings.
    pub(super) fn acknowledged_limits_path(&self) -> PathBuf {
        self.run
            .dir
            .join(".agentstar")
            .join("limits_acknowledged.json")
    }

    /// The acknowledged joint-limit warnings (none before the first acknowledgement).
    pub(super) fn acknowledged_limits(&self) -> Result<AcknowledgedLimits> {
        let path = self.acknowledged_limits_path();
        if !path.is_file() {
            return Ok(AcknowledgedLimits::default());
        }
        let text = agentstar_data::read_text(&path)?;
        serde_json::from_str(&text).map_err(|e| {
            AgentError::Tool(format!(
                "{}: not a record of acknowledged limits ({e}); delete it to start afresh",
                path.display()
            ))
        })
    }

    /// Acknowledges `found` and says so in a line for the reply.
    pub(super) fn acknowledge_limits(&self, found: &[JointAtLimit]) -> Result<String> {
        let mut record = self.acknowledged_limits()?;
        let added = record.acknowledge(found);
        let path = self.acknowledged_limits_path();
        if let Some(dir) = path.parent() {
            std::fs::create_dir_all(dir).map_err(|e| agentstar_data::DataError::io(dir, e))?;
        }
        let text = serde_json::to_string_pretty(&record)
            .map_err(|e| AgentError::Tool(format!("encoding acknowledged limits: {e}")))?;
        agentstar_data::atomic::write_atomic(&path, text.as_bytes())?;
        Ok(if found.is_empty() {
            "acknowledge_limits: no joint-limit warning to acknowledge".to_string()
        } else {
            format!(
                "acknowledged {added} new joint-limit warning(s) ({} in this reply): later replies summarise them in one line while the joint, limit and keyframes stay the same",
                found.len()
            )
        })
    }
}
