//! `track`'s warm start, as its command and its tool both read it, with the rule they share.

use std::path::Path;

/// The warm-start options of `track`: `from` (the poses refined instead of tracking from
/// scratch), `anchors` (keyframes kept exactly) and `keep_basins` (polish only).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct WarmStart<'a> {
    pub from: Option<&'a Path>,
    pub anchors: Option<&'a str>,
    pub keep_basins: bool,
}

impl WarmStart<'_> {
    /// `anchors` and `keep_basins` belong to a warm start and need `from`; a blank `from` is
    /// a mistake, not a request to start over (issue 35).
    pub fn check(&self) -> Result<(), String> {
        if self
            .from
            .is_some_and(|f| f.to_string_lossy().trim().is_empty())
        {
            return Err("`from` is blank; name a pose file (\"pose.json\" for the current poses) or leave it out to track from scratch".into());
        }
        if self.from.is_none() && self.anchors.is_some() {
            return Err("`anchors` keeps keyframes of a warm start; give `from` too (\"pose.json\" for the current poses)".into());
        }
        if self.from.is_none() && self.keep_basins {
            return Err("`keep_basins` keeps the basins of a warm start; give `from` too (\"pose.json\" for the current poses)".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn anchors_and_keep_basins_need_a_from_that_is_not_blank() {
        let start = |from: Option<&'static str>, anchors: Option<&'static str>, keep_basins| {
            WarmStart {
                from: from.map(Path::new),
                anchors,
                keep_basins,
            }
            .check()
        };
        assert_eq!(start(None, None, false), Ok(()));
        assert_eq!(start(Some("pose.json"), Some("000010"), true), Ok(()));
        let e = start(None, Some("000010"), false).expect_err("anchors alone");
        assert!(e.starts_with("`anchors`"), "{e}");
        let e = start(None, None, true).expect_err("keep_basins alone");
        assert!(e.starts_with("`keep_basins`"), "{e}");
        let e = start(Some("  "), None, false).expect_err("blank from");
        assert!(e.contains("blank"), "{e}");
    }
}
