//! Reading and writing the numeric arrays of `.npz` archives (float and integer arrays,
//! any shape), with errors that name the archive and the array.

use crate::{DataError, Result};
use std::path::Path;

/// A numeric array read as `f64` with its shape.
#[derive(Debug, Clone, PartialEq)]
pub struct Array {
    pub shape: Vec<usize>,
    pub data: Vec<f64>,
}

/// Reads the named arrays that exist in the archive (missing names are skipped; callers
/// decide what is required). Booleans read as 0/1.
pub fn read_arrays(path: &Path, names: &[&str]) -> Result<Vec<(String, Array)>> {
    let mut archive = npyz::npz::NpzArchive::open(path)
        .map_err(|e| DataError::invalid(path, format!("not a readable .npz archive: {e}")))?;
    let mut out = Vec::new();
    for &name in names {
        let file = match archive.by_name(name) {
            Ok(Some(f)) => f,
            Ok(None) => continue,
            Err(e) => {
                return Err(DataError::invalid(
                    path,
                    format!("array `{name}` cannot be read: {e}"),
                ))
            }
        };
        out.push((name.to_string(), to_array(file, path, name)?));
    }
    Ok(out)
}

/// Reads a single-array `.npy` file.
pub fn read_npy(path: &Path) -> Result<Array> {
    let bytes = crate::read_bytes(path)?;
    let file = npyz::NpyFile::new(&bytes[..])
        .map_err(|e| DataError::invalid(path, format!("not a readable .npy file: {e}")))?;
    to_array(file, path, "array")
}

fn to_array<R: std::io::Read>(file: npyz::NpyFile<R>, path: &Path, name: &str) -> Result<Array> {
    let shape: Vec<usize> = file.shape().iter().map(|&s| s as usize).collect();
    let dtype = file.dtype();
    let descr = dtype.descr();
    let bad =
        |e: std::io::Error| DataError::invalid(path, format!("array `{name}` ({descr}): {e}"));
    let data: Vec<f64> = match descr
        .trim_matches('\'')
        .trim_start_matches(['<', '>', '|', '='])
    {
        "f8" => file.into_vec::<f64>().map_err(bad)?,
        "f4" => file
            .into_vec::<f32>()
            .map_err(bad)?
            .into_iter()
            .map(f64::from)
            .collect(),
        "i8" => file
            .into_vec::<i64>()
            .map_err(bad)?
            .into_iter()
            .map(|v| v as f64)
            .collect(),
        "i4" => file
            .into_vec::<i32>()
            .map_err(bad)?
            .into_iter()
            .map(f64::from)
            .collect(),
        "u8" => file
            .into_vec::<u64>()
            .map_err(bad)?
            .into_iter()
            .map(|v| v as f64)
            .collect(),
        "u4" => file
            .into_vec::<u32>()
            .map_err(bad)?
            .into_iter()
            .map(f64::from)
            .collect(),
        "u1" => file
            .into_vec::<u8>()
            .map_err(bad)?
            .into_iter()
            .map(f64::from)
            .collect(),
        "b1" => file
            .into_vec::<bool>()
            .map_err(bad)?
            .into_iter()
            .map(|b| if b { 1.0 } else { 0.0 })
            .collect(),
        other => {
            return Err(DataError::invalid(
                path,
                format!(
                    "array `{name}` has unsupported dtype `{other}` (expected float or integer)"
                ),
            ))
        }
    };
    Ok(Array { shape, data })
}

/// Writes `f32` arrays (cameras and point maps) and `i64` arrays into a new archive, atomically.
pub fn write_arrays(
    path: &Path,
    f32_arrays: &[(&str, &[usize], &[f32])],
    i64_arrays: &[(&str, &[usize], &[i64])],
) -> Result<()> {
    let mut buf = std::io::Cursor::new(Vec::new());
    {
        let mut w = npyz::npz::NpzWriter::new(&mut buf);
        for (name, shape, data) in f32_arrays {
            add_array(&mut w, name, shape, data).map_err(|e| DataError::io(path, e))?;
        }
        for (name, shape, data) in i64_arrays {
            add_array(&mut w, name, shape, data).map_err(|e| DataError::io(path, e))?;
        }
    }
    crate::atomic::write_atomic(path, &buf.into_inner())
}

fn add_array<T: npyz::Serialize + npyz::AutoSerialize + Copy, W: std::io::Write + std::io::Seek>(
    w: &mut npyz::npz::NpzWriter<W>,
    name: &str,
    shape: &[usize],
    data: &[T],
) -> std::io::Result<()> {
    use npyz::WriterBuilder;
    let shape: Vec<u64> = shape.iter().map(|&s| s as u64).collect();
    let opts =
        zip::write::FileOptions::default().compression_method(zip::CompressionMethod::Deflated);
    let mut aw = w
        .array::<T>(name, opts)?
        .default_dtype()
        .shape(&shape)
        .begin_nd()?;
    aw.extend(data.iter().copied())?;
    aw.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("a.npz");
        write_arrays(
            &p,
            &[("c2w", &[1, 2, 2], &[1.0, 2.0, 3.0, 4.5])],
            &[("size", &[2], &[640, 480])],
        )
        .expect("write");
        let arrays = read_arrays(&p, &["c2w", "size", "missing"]).expect("read");
        assert_eq!(arrays.len(), 2);
        assert_eq!(
            arrays[0].1,
            Array {
                shape: vec![1, 2, 2],
                data: vec![1.0, 2.0, 3.0, 4.5]
            }
        );
        assert_eq!(arrays[1].1.data, vec![640.0, 480.0]);
        std::fs::write(&p, b"not a zip").expect("write");
        let e = read_arrays(&p, &["c2w"]).expect_err("corrupt");
        assert!(
            e.to_string().contains("a.npz") && e.to_string().contains(".npz archive"),
            "{e}"
        );
    }
}
