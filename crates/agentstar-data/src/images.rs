//! Images and masks on disk: masks are PNGs where a value above 127 marks the region;
//! frames are RGB JPEG or PNG; outputs are written atomically as PNG.

use crate::{DataError, Result};
use agentstar_mask::BitMask;
use image::{GrayImage, RgbImage};
use std::path::Path;

/// Decodes an image file read with a bound, refusing a JPEG without its end-of-image marker
/// (a truncated file, which decoders otherwise fill with grey without complaint) and one
/// whose entropy-coded data does not decode (see [`decode_jpeg_strict`]).
pub fn decode_image(path: &Path, what: &str) -> Result<image::DynamicImage> {
    let bytes = crate::read_bounded(path, crate::limits::IMAGE_BYTES)?;
    let format = image::guess_format(&bytes)
        .map_err(|e| DataError::invalid(path, format!("cannot read {what}: {e}")))?;
    if format == image::ImageFormat::Jpeg && !jpeg_is_complete(&bytes) {
        return Err(DataError::invalid(
            path,
            format!("cannot read {what}: the JPEG is truncated (no end-of-image marker)"),
        ));
    }
    if format == image::ImageFormat::Jpeg {
        return decode_jpeg_strict(&bytes, path, what);
    }
    let mut reader = image::ImageReader::with_format(std::io::Cursor::new(&bytes), format);
    let mut limits = image::Limits::default();
    limits.max_image_width = Some(16384);
    limits.max_image_height = Some(16384);
    reader.limits(limits);
    reader
        .decode()
        .map_err(|e| DataError::invalid(path, format!("cannot read {what}: {e}")))
}

/// Decodes a JPEG after walking its entropy-coded data ([`crate::jpeg_scan`]), with
/// `zune-jpeg` in strict mode (the decoder `image` uses, which `image` runs leniently: a scan
/// that runs out early, an invalid Huffman code or a marker inside the scan give grey or
/// garbage blocks and no error). JPEG has no checksum, so a corruption that still decodes as
/// valid codes cannot be seen; one that desynchronises the stream (nearly every cut or
/// overwritten run of bytes) is an error naming the file. Padding between header segments,
/// which some writers leave, is the one strict check of the decoder forgiven.
fn decode_jpeg_strict(bytes: &[u8], path: &Path, what: &str) -> Result<image::DynamicImage> {
    use zune_core::bytestream::ZCursor;
    use zune_core::colorspace::ColorSpace;
    use zune_core::options::DecoderOptions;
    crate::jpeg_scan::check(bytes).map_err(|e| {
        DataError::invalid(
            path,
            format!(
                "cannot read {what}: the JPEG is corrupt: {e}; re-export or re-extract the frame"
            ),
        )
    })?;
    let decode = |strict: bool| {
        let options = DecoderOptions::default()
            .set_strict_mode(strict)
            .set_max_width(16384)
            .set_max_height(16384)
            .jpeg_set_out_colorspace(ColorSpace::RGB);
        let mut decoder = zune_jpeg::JpegDecoder::new_with_options(ZCursor::new(bytes), options);
        let pixels = decoder.decode()?;
        let (w, h) = decoder
            .dimensions()
            .ok_or(zune_jpeg::errors::DecodeErrors::FormatStatic(
                "no dimensions",
            ))?;
        Ok::<_, zune_jpeg::errors::DecodeErrors>((w, h, pixels))
    };
    let (w, h, pixels) = match decode(true) {
        Err(e) if e.to_string().contains("Extra bytes between headers") => decode(false),
        other => other,
    }
    .map_err(|e| {
        DataError::invalid(
            path,
            format!(
                "cannot read {what}: the JPEG is corrupt ({e}); re-export or re-extract the frame"
            ),
        )
    })?;
    RgbImage::from_raw(w as u32, h as u32, pixels)
        .map(image::DynamicImage::ImageRgb8)
        .ok_or_else(|| {
            DataError::invalid(
                path,
                format!("cannot read {what}: the JPEG decoder returned too few pixels"),
            )
        })
}

/// A JPEG ends with the EOI marker `FF D9` (some writers pad a few bytes after it).
pub(crate) fn jpeg_is_complete(bytes: &[u8]) -> bool {
    let tail = &bytes[bytes.len().saturating_sub(64)..];
    tail.windows(2).any(|w| w == [0xFF, 0xD9])
}

pub fn load_rgb(path: &Path) -> Result<RgbImage> {
    Ok(decode_image(path, "image")?.to_rgb8())
}

/// Reads a binary mask (> 127 = inside), any PNG colour type (luma of the first channel).
pub fn load_mask(path: &Path) -> Result<BitMask> {
    let g = decode_image(path, "mask")?.to_luma8();
    Ok(BitMask::from_fn(g.width(), g.height(), |x, y| {
        g.get_pixel(x, y)[0] > 127
    }))
}

/// Image size without decoding the pixels (only regular files within the image limit).
pub fn image_size(path: &Path) -> Result<(u32, u32)> {
    let meta = std::fs::metadata(path).map_err(|e| DataError::io(path, e))?;
    if !meta.is_file() {
        return Err(DataError::invalid(
            path,
            "cannot read image: not a regular file",
        ));
    }
    if meta.len() > crate::limits::IMAGE_BYTES {
        return Err(DataError::invalid(
            path,
            format!(
                "cannot read image: larger than the limit of {} MiB",
                crate::limits::IMAGE_BYTES >> 20
            ),
        ));
    }
    image::image_dimensions(path)
        .map_err(|e| DataError::invalid(path, format!("cannot read image: {e}")))
}

pub fn mask_to_gray(mask: &BitMask) -> GrayImage {
    GrayImage::from_fn(mask.width(), mask.height(), |x, y| {
        image::Luma([if mask.get(x, y) { 255 } else { 0 }])
    })
}

fn encode_png(
    write: impl FnOnce(&mut std::io::Cursor<Vec<u8>>) -> image::ImageResult<()>,
    path: &Path,
) -> Result<Vec<u8>> {
    let mut buf = std::io::Cursor::new(Vec::new());
    write(&mut buf).map_err(|e| DataError::invalid(path, format!("cannot encode PNG: {e}")))?;
    Ok(buf.into_inner())
}

pub fn save_png_rgb(img: &RgbImage, path: &Path) -> Result<()> {
    let bytes = encode_png(|b| img.write_to(b, image::ImageFormat::Png), path)?;
    crate::atomic::write_atomic(path, &bytes)
}

pub fn save_png_rgba(img: &image::RgbaImage, path: &Path) -> Result<()> {
    let bytes = encode_png(|b| img.write_to(b, image::ImageFormat::Png), path)?;
    crate::atomic::write_atomic(path, &bytes)
}

pub fn save_png_gray(img: &GrayImage, path: &Path) -> Result<()> {
    let bytes = encode_png(|b| img.write_to(b, image::ImageFormat::Png), path)?;
    crate::atomic::write_atomic(path, &bytes)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A textured 96 × 64 frame as a baseline JPEG (real entropy-coded data in every block).
    fn textured_jpeg() -> (RgbImage, Vec<u8>) {
        let img = RgbImage::from_fn(96, 64, |x, y| {
            let v = ((x * 37 + y * 91) ^ (x * y)) as u8;
            image::Rgb([v, v.wrapping_mul(3), 255 - v])
        });
        let mut bytes = Vec::new();
        image::codecs::jpeg::JpegEncoder::new_with_quality(&mut bytes, 90)
            .encode_image(&img)
            .expect("encode");
        (img, bytes)
    }

    /// Where the entropy-coded data starts: after the start-of-scan segment.
    fn scan_start(bytes: &[u8]) -> usize {
        let sos = bytes
            .windows(2)
            .position(|w| w == [0xFF, 0xDA])
            .expect("SOS");
        let len = u16::from_be_bytes([bytes[sos + 2], bytes[sos + 3]]) as usize;
        sos + 2 + len
    }

    fn error_of(r: Result<RgbImage>) -> String {
        match r {
            Ok(_) => panic!("decoded without an error"),
            Err(e) => e.to_string(),
        }
    }

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, bytes).expect("write");
        p
    }

    #[test]
    fn a_whole_jpeg_decodes_close_to_its_pixels() {
        let dir = tempfile::tempdir().expect("tmp");
        let (img, bytes) = textured_jpeg();
        let back = load_rgb(&write(dir.path(), "ok.jpg", &bytes)).expect("decode");
        assert_eq!(back.dimensions(), img.dimensions());
        let err: f64 = img
            .pixels()
            .zip(back.pixels())
            .map(|(a, b)| {
                (0..3)
                    .map(|c| (a[c] as f64 - b[c] as f64).abs())
                    .sum::<f64>()
            })
            .sum::<f64>()
            / (96.0 * 64.0 * 3.0);
        assert!(err < 12.0, "mean abs error {err}");
    }

    /// Issue 16: a JPEG cut in the middle of its entropy-coded data (with its end-of-image
    /// marker put back, as a careless copy or a re-muxer leaves it) or with bytes of that
    /// data overwritten decoded with grey or garbage blocks and no complaint.
    #[test]
    fn a_jpeg_corrupted_mid_stream_is_an_error_naming_the_file() {
        let dir = tempfile::tempdir().expect("tmp");
        let (_, bytes) = textured_jpeg();
        let start = scan_start(&bytes);
        let end = bytes.len() - 2;
        assert!(end - start > 1000, "scan of {} bytes", end - start);

        // Cut halfway through the scan, end-of-image marker kept.
        let mut cut = bytes[..start + (end - start) / 2].to_vec();
        cut.extend_from_slice(&[0xFF, 0xD9]);
        let p = write(dir.path(), "cut.jpg", &cut);
        let e = error_of(load_rgb(&p));
        assert!(e.contains("cut.jpg") && e.contains("corrupt"), "{e}");

        // A run of bytes in the middle of the scan overwritten.
        let mut flipped = bytes.clone();
        let mid = start + (end - start) / 3;
        for b in &mut flipped[mid..mid + 16] {
            *b = if *b == 0xFF { 0x00 } else { !*b & 0xFE };
        }
        let p = write(dir.path(), "flipped.jpg", &flipped);
        let e = error_of(load_rgb(&p));
        assert!(e.contains("flipped.jpg") && e.contains("corrupt"), "{e}");

        // Truncated without the marker: named as before.
        let p = write(dir.path(), "short.jpg", &bytes[..start + 100]);
        let e = error_of(load_rgb(&p));
        assert!(e.contains("short.jpg") && e.contains("truncated"), "{e}");
    }

    /// The walk refuses nothing a common writer makes: ffmpeg's JPEGs (4:2:0, 4:4:4, grey,
    /// optimal Huffman tables, restart intervals) decode. Needs ffmpeg (CI installs it).
    #[test]
    fn jpegs_written_by_ffmpeg_pass_the_scan_walk() {
        let dir = tempfile::tempdir().expect("tmp");
        let runs = [
            ("420.jpg", vec!["-pix_fmt", "yuvj420p"]),
            ("444.jpg", vec!["-pix_fmt", "yuvj444p"]),
            ("grey.jpg", vec!["-pix_fmt", "gray"]),
            (
                "optimal.jpg",
                vec!["-pix_fmt", "yuvj422p", "-huffman", "optimal"],
            ),
        ];
        for (name, args) in runs {
            let out = dir.path().join(name);
            let status = std::process::Command::new("ffmpeg")
                .args([
                    "-v",
                    "error",
                    "-y",
                    "-f",
                    "lavfi",
                    "-i",
                    "testsrc2=size=160x120",
                ])
                .args(["-frames:v", "1", "-q:v", "3"])
                .args(&args)
                .arg(&out)
                .status();
            match status {
                Err(_) => {
                    eprintln!("ffmpeg not found: test not run");
                    return;
                }
                Ok(s) => assert!(s.success(), "ffmpeg {name}"),
            }
            let img = load_rgb(&out).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_eq!(img.dimensions(), (160, 120), "{name}");
        }
    }
}
