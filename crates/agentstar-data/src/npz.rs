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
/// decide what is required). Booleans read as 0/1. Every array's bytes are read whole, so
/// the zip entry's CRC-32 is checked (a flipped byte is an error, not a changed value), and
/// Fortran-order arrays are returned in C order.
pub fn read_arrays(path: &Path, names: &[&str]) -> Result<Vec<(String, Array)>> {
    let bytes = crate::read_bytes(path)?;
    read_arrays_from(&bytes, path, names)
}

/// [`read_arrays`] on an archive already in memory; `path` only names it in errors.
pub fn read_arrays_from(bytes: &[u8], path: &Path, names: &[&str]) -> Result<Vec<(String, Array)>> {
    use std::io::Read;
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(bytes))
        .map_err(|e| DataError::invalid(path, format!("not a readable .npz archive: {e}")))?;
    let mut out = Vec::new();
    for &name in names {
        let entry_name = npyz::npz::file_name_from_array_name(name);
        let mut entry = match archive.by_name(&entry_name) {
            Ok(f) => f,
            Err(zip::result::ZipError::FileNotFound) => continue,
            Err(e) => {
                return Err(DataError::invalid(
                    path,
                    format!("array `{name}` cannot be read: {e}"),
                ))
            }
        };
        let limit = crate::limits::NPZ_ENTRY_BYTES;
        let mut data = Vec::new();
        (&mut entry)
            .take(limit + 1)
            .read_to_end(&mut data)
            .map_err(|e| {
                DataError::invalid(
                    path,
                    format!("array `{name}` cannot be read (corrupt archive entry: {e})"),
                )
            })?;
        if data.len() as u64 > limit {
            return Err(DataError::invalid(
                path,
                format!(
                    "array `{name}` is larger than the limit of {} GiB decompressed",
                    limit >> 30
                ),
            ));
        }
        out.push((name.to_string(), parse_npy(&data, path, name)?));
    }
    Ok(out)
}

/// Reads a single-array `.npy` file.
pub fn read_npy(path: &Path) -> Result<Array> {
    let bytes = crate::read_bytes(path)?;
    parse_npy(&bytes, path, "array")
}

/// Parses one `.npy` document held in memory; `path` and `name` only name it in errors.
pub fn parse_npy(bytes: &[u8], path: &Path, name: &str) -> Result<Array> {
    let file = npyz::NpyFile::new(bytes).map_err(|e| {
        DataError::invalid(
            path,
            format!("array `{name}` is not a readable .npy array: {e}"),
        )
    })?;
    to_array(file, bytes.len(), path, name)
}

fn item_bytes(descr: &str) -> Option<u64> {
    descr
        .trim_start_matches(|c: char| !c.is_ascii_digit())
        .parse()
        .ok()
}

fn to_array<R: std::io::Read>(
    file: npyz::NpyFile<R>,
    available: usize,
    path: &Path,
    name: &str,
) -> Result<Array> {
    let shape: Vec<usize> = file.shape().iter().map(|&s| s as usize).collect();
    let fortran = file.order() == npyz::Order::Fortran;
    let dtype = file.dtype();
    let descr = dtype.descr();
    let bad =
        |e: std::io::Error| DataError::invalid(path, format!("array `{name}` ({descr}): {e}"));
    let plain = descr
        .trim_matches('\'')
        .trim_start_matches(['<', '>', '|', '=']);
    // The header's shape must fit in the bytes that follow it (a claim of 10¹² elements in
    // a small file is an error, not an allocation).
    let count = file
        .shape()
        .iter()
        .try_fold(1u64, |acc, &d| acc.checked_mul(d));
    let needed = count.and_then(|c| item_bytes(plain).and_then(|b| c.checked_mul(b)));
    if needed.is_none_or(|n| n > available as u64) {
        return Err(DataError::invalid(
            path,
            format!(
                "array `{name}` claims shape {shape:?} ({descr}), more than the {available} bytes it holds"
            ),
        ));
    }
    let data: Vec<f64> = match plain {
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
    let data = if fortran && shape.len() > 1 {
        fortran_to_c(&shape, &data)
    } else {
        data
    };
    Ok(Array { shape, data })
}

/// Reorders a Fortran-order (first index fastest) buffer into C order (last index fastest).
fn fortran_to_c(shape: &[usize], data: &[f64]) -> Vec<f64> {
    let n = data.len();
    let mut out = Vec::with_capacity(n);
    let mut index = vec![0usize; shape.len()];
    // Fortran strides: 1, d0, d0·d1, …
    let mut strides = vec![1usize; shape.len()];
    for k in 1..shape.len() {
        strides[k] = strides[k - 1] * shape[k - 1];
    }
    for _ in 0..n {
        let at: usize = index.iter().zip(&strides).map(|(i, s)| i * s).sum();
        out.push(data[at]);
        // Advance the C-order multi-index (last axis fastest).
        for k in (0..shape.len()).rev() {
            index[k] += 1;
            if index[k] < shape[k] {
                break;
            }
            index[k] = 0;
        }
    }
    out
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

    /// A `.npy` document as numpy writes it, version 1.0.
    fn npy(descr: &str, fortran: bool, shape: &str, payload: &[u8]) -> Vec<u8> {
        let mut header = format!(
            "{{'descr': '{descr}', 'fortran_order': {}, 'shape': {shape}, }}",
            if fortran { "True" } else { "False" }
        );
        while (10 + header.len() + 1) % 64 != 0 {
            header.push(' ');
        }
        header.push('\n');
        let mut out = b"\x93NUMPY\x01\x00".to_vec();
        out.extend((header.len() as u16).to_le_bytes());
        out.extend(header.as_bytes());
        out.extend(payload);
        out
    }

    #[test]
    fn fortran_order_arrays_are_read_in_c_order() {
        // numpy.asfortranarray([[1, 2, 3], [4, 5, 6]]) stores 1 4 2 5 3 6.
        let payload: Vec<u8> = [1.0f64, 4.0, 2.0, 5.0, 3.0, 6.0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let a = parse_npy(
            &npy("<f8", true, "(2, 3)", &payload),
            Path::new("x.npy"),
            "a",
        )
        .expect("fortran");
        assert_eq!(a.shape, vec![2, 3]);
        assert_eq!(a.data, vec![1.0, 2.0, 3.0, 4.0, 5.0, 6.0]);
        let c = parse_npy(
            &npy("<f8", false, "(2, 3)", &payload),
            Path::new("x.npy"),
            "a",
        )
        .expect("c");
        assert_eq!(c.data, vec![1.0, 4.0, 2.0, 5.0, 3.0, 6.0]);
        // Three axes: element (i, j, k) of a (2, 3, 2) array stored at i + 2j + 6k.
        let mut stored = [0.0f64; 12];
        for i in 0..2 {
            for j in 0..3 {
                for k in 0..2 {
                    stored[i + 2 * j + 6 * k] = (100 * i + 10 * j + k) as f64;
                }
            }
        }
        let bytes: Vec<u8> = stored.iter().flat_map(|v| v.to_le_bytes()).collect();
        let a = parse_npy(
            &npy("<f8", true, "(2, 3, 2)", &bytes),
            Path::new("x.npy"),
            "a",
        )
        .expect("3-d");
        let expect: Vec<f64> = (0..2)
            .flat_map(|i| {
                (0..3).flat_map(move |j| (0..2).map(move |k| (100 * i + 10 * j + k) as f64))
            })
            .collect();
        assert_eq!(a.shape, vec![2, 3, 2]);
        assert_eq!(a.data, expect);
    }

    #[test]
    fn a_shape_larger_than_the_data_is_an_error() {
        let doc = npy("<f8", false, "(1000000000000,)", &[0; 16]);
        let e = parse_npy(&doc, Path::new("x.npy"), "c2w").expect_err("short");
        assert!(
            e.to_string().contains("c2w") && e.to_string().contains("claims shape"),
            "{e}"
        );
    }

    #[test]
    fn a_flipped_byte_fails_the_crc_check() {
        let dir = tempfile::tempdir().expect("tmp");
        let p = dir.path().join("cameras.npz");
        let values: Vec<f32> = (0..64).map(|i| i as f32 * 0.25 + 1000.0).collect();
        // Stored, not deflated: a flipped payload byte then still "decompresses".
        let mut buf = std::io::Cursor::new(Vec::new());
        {
            use npyz::WriterBuilder;
            let mut w = npyz::npz::NpzWriter::new(&mut buf);
            let opts = zip::write::FileOptions::default()
                .compression_method(zip::CompressionMethod::Stored);
            let mut aw = w
                .array::<f32>("c2w", opts)
                .expect("array")
                .default_dtype()
                .shape(&[4, 4, 4])
                .begin_nd()
                .expect("begin");
            aw.extend(values.iter().copied()).expect("extend");
            aw.finish().expect("finish");
        }
        let mut bytes = buf.into_inner();
        std::fs::write(&p, &bytes).expect("write");
        assert_eq!(
            read_arrays(&p, &["c2w"]).expect("intact")[0].1.data[5],
            1001.25
        );
        let at = bytes
            .windows(4)
            .position(|w| w == 1000.25f32.to_le_bytes())
            .expect("value in the archive");
        bytes[at + 1] ^= 0x40;
        std::fs::write(&p, &bytes).expect("write");
        let e = read_arrays(&p, &["c2w"]).expect_err("crc");
        assert!(
            e.to_string().contains("cameras.npz") && e.to_string().contains("c2w"),
            "{e}"
        );
    }
}
