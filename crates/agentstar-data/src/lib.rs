//! Every file format agentstar reads or writes: captures (capture/v1), `pose.json`, mesh
//! files (OBJ, STL, PLY, GLB), URDF models, GLB and URDF export, images and masks.
//!
//! This is the only library crate that touches the file system. Every writer goes through
//! [`atomic::write_atomic`] (temporary file, then rename), so a failure never leaves a
//! half-written file behind. Bad input is reported with the file and what is wrong.

pub mod animation;
pub mod atomic;
pub mod bakefile;
pub mod capture;
pub mod capture_writer;
pub mod export;
pub mod glb;
pub(crate) mod gltf_write;
pub mod gt;
pub mod history;
pub mod images;
pub mod jpeg_scan;
pub mod ledger;
pub mod meshio;
pub mod npz;
pub mod posefile;
pub mod poses;
pub mod rundir;
pub mod runfile;
pub mod scenefile;
pub mod texture;
pub mod urdf;

use std::path::{Path, PathBuf};

/// A data error names the file and what is wrong with it.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
    /// The message already holds the I/O error, so it is not also reported as a source
    /// (which would print it twice in an error chain).
    #[error("{path}: {error}")]
    Io {
        path: PathBuf,
        error: std::io::Error,
    },
    #[error("{0}")]
    Scene(#[from] agentstar_scene::SceneError),
    /// Frames named that the capture does not offer (an unknown frame, an in-between frame
    /// where keyframes are taken): the request is at fault, not the capture's files.
    #[error("{message} (capture {dir})")]
    Selection { dir: PathBuf, message: String },
}

impl DataError {
    pub fn invalid(path: impl AsRef<Path>, message: impl Into<String>) -> Self {
        DataError::Invalid {
            path: path.as_ref().to_path_buf(),
            message: message.into(),
        }
    }
    pub fn io(path: impl AsRef<Path>, error: std::io::Error) -> Self {
        DataError::Io {
            path: path.as_ref().to_path_buf(),
            error,
        }
    }
}

pub type Result<T, E = DataError> = std::result::Result<T, E>;

/// The most bytes agentstar reads from one file of each kind. Every file the program opens
/// is read through [`read_bounded`] (or a reader built on it), so a symlink to `/dev/zero`,
/// a FIFO or a huge file is an error naming the file and the limit, never a hang.
pub mod limits {
    /// JSON documents, scene scripts, URDF and other text files.
    pub const TEXT_BYTES: u64 = 256 << 20;
    /// Mesh files and `.npz` archives.
    pub const BINARY_BYTES: u64 = 2 << 30;
    /// One image (frame, mask, depth PNG).
    pub const IMAGE_BYTES: u64 = 512 << 20;
    /// One array inside an `.npz` archive, decompressed.
    pub const NPZ_ENTRY_BYTES: u64 = 2 << 30;
}

fn human_bytes(n: u64) -> String {
    if n >= 1 << 30 && n.is_multiple_of(1 << 30) {
        format!("{} GiB", n >> 30)
    } else if n >= 1 << 20 {
        format!("{} MiB", n >> 20)
    } else {
        format!("{n} bytes")
    }
}

/// Reads at most `limit` bytes of a regular file: a directory, device, FIFO or socket is
/// refused before it is opened for reading, and a file longer than `limit` is an error that
/// names the file and the limit (what it holds is never read past the limit).
pub fn read_bounded(path: &Path, limit: u64) -> Result<Vec<u8>> {
    use std::io::Read;
    let meta = std::fs::metadata(path).map_err(|e| DataError::io(path, e))?;
    if !meta.is_file() {
        let what = if meta.is_dir() {
            "a directory"
        } else {
            "not a regular file (a device, FIFO or socket)"
        };
        return Err(DataError::invalid(
            path,
            format!("is {what}; expected a regular file"),
        ));
    }
    let too_big = || {
        DataError::invalid(
            path,
            format!(
                "is larger than the limit of {} for this kind of file",
                human_bytes(limit)
            ),
        )
    };
    if meta.len() > limit {
        return Err(too_big());
    }
    let file = std::fs::File::open(path).map_err(|e| DataError::io(path, e))?;
    let mut bytes = Vec::with_capacity(meta.len() as usize);
    file.take(limit.saturating_add(1))
        .read_to_end(&mut bytes)
        .map_err(|e| DataError::io(path, e))?;
    if bytes.len() as u64 > limit {
        return Err(too_big());
    }
    Ok(bytes)
}

/// Reads a whole binary file (meshes, archives), bounded by [`limits::BINARY_BYTES`].
pub fn read_bytes(path: &Path) -> Result<Vec<u8>> {
    read_bounded(path, limits::BINARY_BYTES)
}

/// Reads a whole UTF-8 text file, bounded by [`limits::TEXT_BYTES`].
pub fn read_text(path: &Path) -> Result<String> {
    let bytes = read_bounded(path, limits::TEXT_BYTES)?;
    String::from_utf8(bytes).map_err(|e| {
        DataError::invalid(
            path,
            format!(
                "is not UTF-8 text (invalid byte at offset {})",
                e.utf8_error().valid_up_to()
            ),
        )
    })
}

/// A path as one shell word for the commands we print for people to copy: left alone when
/// it holds only safe characters, else in single quotes (a `'` inside becomes `'\''`).
pub fn shell_quote(path: &Path) -> String {
    let s = path.to_string_lossy();
    let safe = !s.is_empty()
        && s.chars()
            .all(|c| c.is_ascii_alphanumeric() || "/._-+:,@%=".contains(c));
    if safe {
        s.into_owned()
    } else {
        format!("'{}'", s.replace('\'', "'\\''"))
    }
}

/// Parses a JSON document read from `path`, explaining the mistakes a JSON parser reports
/// only as a position: a byte-order mark, and `NaN`/`Infinity` (which Python's `json.dump`
/// writes but JSON does not allow).
pub fn parse_json<T: serde::de::DeserializeOwned>(text: &str) -> std::result::Result<T, String> {
    if text.starts_with('\u{feff}') {
        return Err(
            "the file starts with a UTF-8 byte-order mark (BOM), which JSON does not allow; save it as UTF-8 without a BOM".into(),
        );
    }
    serde_json::from_str(text).map_err(|e| {
        let mut msg = e.to_string();
        if let Some(token) = non_finite_token_at(text, e.line(), e.column()) {
            msg.push_str(&format!(
                " (`{token}` is not JSON: JSON has no NaN or Infinity; write null where a value is unknown, or a finite number)"
            ));
        }
        msg
    })
}

fn non_finite_token_at(text: &str, line: usize, column: usize) -> Option<&'static str> {
    let l = text.lines().nth(line.checked_sub(1)?)?;
    // serde_json's column points at (or just past) the offending character.
    let start = l
        .char_indices()
        .nth(column.saturating_sub(1))
        .map_or(l.len(), |(i, _)| i);
    // The byte just after the last character that cannot be part of the word (which may be
    // several bytes long: the slice must start on a character boundary).
    let from = l[..start]
        .char_indices()
        .rev()
        .find(|&(_, c)| !(c.is_ascii_alphabetic() || c == '-' || c == '+'))
        .map_or(0, |(i, c)| i + c.len_utf8());
    let word: String = l[from..]
        .chars()
        .take_while(|c| c.is_ascii_alphabetic() || *c == '-' || *c == '+')
        .collect();
    let word = word.trim_start_matches(['-', '+']);
    ["NaN", "Infinity", "inf", "nan", "Inf"]
        .into_iter()
        .find(|t| word.eq_ignore_ascii_case(t))
        .map(|_| {
            if word.eq_ignore_ascii_case("nan") {
                "NaN"
            } else {
                "Infinity"
            }
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounded_reads_refuse_devices_and_long_files() {
        let e = read_bounded(Path::new("/dev/zero"), 1 << 20).expect_err("device");
        assert!(
            e.to_string().contains("/dev/zero") && e.to_string().contains("regular file"),
            "{e}"
        );
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("capture.json");
        std::fs::write(&p, vec![b' '; 2000]).expect("write");
        let e = read_bounded(&p, 1000).expect_err("long");
        assert!(
            e.to_string().contains("capture.json") && e.to_string().contains("1000 bytes"),
            "{e}"
        );
        assert_eq!(read_bounded(&p, 2000).expect("fits").len(), 2000);
        #[cfg(unix)]
        {
            let link = dir.path().join("zero.json");
            std::os::unix::fs::symlink("/dev/zero", &link).expect("symlink");
            let e = read_text(&link).expect_err("symlink to a device");
            assert!(e.to_string().contains("zero.json"), "{e}");
        }
    }

    #[test]
    fn printed_paths_are_quoted_for_the_shell() {
        assert_eq!(
            shell_quote(Path::new("/tmp/run-1/pose.json")),
            "/tmp/run-1/pose.json"
        );
        assert_eq!(
            shell_quote(Path::new("/tmp/my run/pose.json")),
            "'/tmp/my run/pose.json'"
        );
        assert_eq!(shell_quote(Path::new("it's")), "'it'\\''s'");
        assert_eq!(shell_quote(Path::new("")), "''");
    }

    #[test]
    fn json_messages_explain_bom_and_nan() {
        let e = parse_json::<serde_json::Value>("\u{feff}{\"a\": 1}").expect_err("bom");
        assert!(e.contains("byte-order mark"), "{e}");
        let e = parse_json::<serde_json::Value>("{\"a\": [1, NaN]}").expect_err("nan");
        assert!(e.contains("`NaN`") && e.contains("null"), "{e}");
        let e = parse_json::<serde_json::Value>("{\"a\":\n -Infinity}").expect_err("inf");
        assert!(e.contains("`Infinity`"), "{e}");
        let e = parse_json::<serde_json::Value>("{\"a\": nope}").expect_err("other");
        assert!(!e.contains("NaN"), "{e}");
    }

    #[test]
    fn json_messages_survive_multibyte_characters_before_the_error() {
        // Found by the fuzz harness: a two-byte character just before the error position
        // made the word search slice inside it and panic.
        for text in [
            "{\n    \"0000\u{ff}x",
            "{\"frame_con\u{ff}venti",
            "{\"a\": \u{ff}NaN}",
        ] {
            let e = parse_json::<serde_json::Value>(text).expect_err("not JSON");
            assert!(!e.is_empty());
        }
        let e = parse_json::<serde_json::Value>("{\"a\": [\u{e9}NaN]}").expect_err("nan");
        assert!(!e.is_empty(), "{e}");
    }
}
