//! Golden images for the renderer's tests and for those of crates that render through it
//! (`crates/agentstar-data/tests/appearance.rs` includes this file by path): each crate's
//! goldens stand in its own `tests/golden`.
#![allow(dead_code)]

/// Compares `img` with the small committed golden image `tests/golden/NAME` of the crate
/// under test, within explicit tolerances (a mean channel difference under 2 and under 1% of
/// pixels more than 24 off). Run with `AGENTSTAR_BLESS=1` to rewrite the golden after an
/// intended change, then look at it.
pub fn assert_golden(name: &str, img: &image::RgbImage) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/golden")
        .join(name);
    if std::env::var_os("AGENTSTAR_BLESS").is_some() {
        std::fs::create_dir_all(path.parent().expect("dir")).expect("mkdir");
        img.save(&path).expect("bless");
    }
    let golden = image::open(&path)
        .unwrap_or_else(|e| panic!("{}: {e} (run with AGENTSTAR_BLESS=1 once)", path.display()))
        .to_rgb8();
    assert_eq!(golden.dimensions(), img.dimensions(), "{name}");
    let (mut total, mut far) = (0u64, 0u32);
    for (a, b) in golden.pixels().zip(img.pixels()) {
        let d = (0..3)
            .map(|k| (a[k] as i32 - b[k] as i32).unsigned_abs())
            .max()
            .unwrap_or(0);
        total += u64::from(d);
        if d > 24 {
            far += 1;
        }
    }
    let n = f64::from(img.width() * img.height());
    assert!(
        (total as f64) / n < 2.0 && f64::from(far) < 0.01 * n,
        "{name}: mean diff {:.2}, {far} pixels far off",
        total as f64 / n
    );
}
