//! `rmvp calibrate` on real photographs as they come: OpenCV's own chessboard pictures
//! (JPEG, from Debian's opencv-doc package), the same pixels as PNG and TIFF, a set where some
//! pictures disagree with the others, and pictures whose files name different cameras.

use image::{GrayImage, ImageEncoder};
use rmvp_testkit::{exif_block, opencv_photographs};
use serde_json::Value;
use std::path::{Path, PathBuf};

mod common;
use common::{fails, ok, rmvp, s};

/// OpenCV 4.6's `calibrateCamera` on the same 13 photographs (Debian 12's python3-opencv,
/// `bench/opencv_calibrate.py`): `imread(IMREAD_GRAYSCALE)`, `findChessboardCorners` with its
/// default flags, `cornerSubPix` over 5x5 (rmvp's window), `CALIB_FIX_K3 |
/// CALIB_ZERO_TANGENT_DIST` (rmvp's default model). Its principal point is in OpenCV's pixel
/// convention, half a pixel from rmvp's.
const OPENCV_RMS_PX: f64 = 0.20417;
const OPENCV_K: [f64; 4] = [533.106, 533.458, 342.442, 233.204];

fn calibrate(inputs: &[PathBuf], output: &Path) -> (Value, String) {
    let mut args = vec!["calibrate", "--board", "chessboard", "--squares", "10x7", "--square-mm", "25"];
    args.extend(inputs.iter().map(|p| s(p)));
    args.extend(["-o", s(output)]);
    let out = rmvp(&args);
    let text = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "{text}");
    (serde_json::from_str(&std::fs::read_to_string(output).unwrap()).unwrap(), text)
}

fn grey(path: &Path) -> GrayImage {
    image::open(path).unwrap().into_luma8()
}

#[test]
fn jpeg_photographs_calibrate_as_opencv_does() {
    let tmp = tempfile::tempdir().unwrap();
    let photos = opencv_photographs();
    let (jpeg, text) = calibrate(&photos, &tmp.path().join("jpeg.json"));
    let rms = jpeg["rms_px"].as_f64().unwrap();
    let k = |r: usize, c: usize| jpeg["k"][r][c].as_f64().unwrap();
    eprintln!(
        "rmvp RMS {rms:.5} px, OpenCV {OPENCV_RMS_PX}; fx {:.3} fy {:.3} cx {:.3} cy {:.3}",
        k(0, 0),
        k(1, 1),
        k(0, 2),
        k(1, 2)
    );
    assert!((rms / OPENCV_RMS_PX - 1.0).abs() < 0.02, "RMS {rms} against OpenCV's {OPENCV_RMS_PX}");
    assert!((k(0, 0) / OPENCV_K[0] - 1.0).abs() < 1e-3 && (k(1, 1) / OPENCV_K[1] - 1.0).abs() < 1e-3);
    assert!((k(0, 2) - OPENCV_K[2] - 0.5).abs() < 0.1 && (k(1, 2) - OPENCV_K[3] - 0.5).abs() < 0.1);
    assert_eq!(jpeg["images"].as_array().unwrap().len(), 13);
    assert!(!text.contains("warning"), "{text}");

    // The same pixels as 8-bit PNG and TIFF: the same calibration (no second encoding).
    for extension in ["png", "tif"] {
        let copies: Vec<PathBuf> = photos
            .iter()
            .map(|p| {
                let copy = tmp.path().join(p.file_name().unwrap()).with_extension(extension);
                grey(p).save(&copy).unwrap();
                copy
            })
            .collect();
        let (again, _) = calibrate(&copies, &tmp.path().join(format!("{extension}.json")));
        assert_eq!(again["k"], jpeg["k"], "{extension}");
        assert_eq!(again["rms_px"], jpeg["rms_px"], "{extension}");
    }
}

/// `image` with a smooth wobble of `amplitude` pixels: what a board that is not flat does to
/// its corners, which no pose or lens can explain.
fn wobbled(image: &GrayImage, amplitude: f32) -> GrayImage {
    let (w, h) = image.dimensions();
    let wave = |t: u32| amplitude * (std::f32::consts::TAU * t as f32 / 90.0).sin();
    GrayImage::from_fn(w, h, |x, y| {
        let (u, v) = ((x as f32 + wave(y)).clamp(0.0, (w - 1) as f32), (y as f32 + wave(x)).clamp(0.0, (h - 1) as f32));
        let (x0, y0) = (u.floor() as u32, v.floor() as u32);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (u - x0 as f32, v - y0 as f32);
        let p = |x, y| image.get_pixel(x, y)[0] as f32;
        let value =
            (p(x0, y0) * (1.0 - fx) + p(x1, y0) * fx) * (1.0 - fy) + (p(x0, y1) * (1.0 - fx) + p(x1, y1) * fx) * fy;
        image::Luma([(value + 0.5).clamp(0.0, 255.0) as u8])
    })
}

#[test]
fn pictures_whose_errors_form_a_second_group_are_named_in_a_warning() {
    let tmp = tempfile::tempdir().unwrap();
    let inputs: Vec<PathBuf> = opencv_photographs()
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let copy = tmp.path().join(p.file_name().unwrap()).with_extension("png");
            let picture = grey(p);
            if [1, 5, 10].contains(&i) { wobbled(&picture, 1.5) } else { picture }.save(&copy).unwrap();
            copy
        })
        .collect();
    let (calibration, text) = calibrate(&inputs, &tmp.path().join("camera.json"));
    let warnings = calibration["warnings"].as_array().unwrap();
    assert_eq!(warnings.len(), 1, "{text}");
    let warning = warnings[0].as_str().unwrap();
    assert!(text.contains(warning), "{text}");
    for (i, p) in inputs.iter().enumerate() {
        let name = p.file_name().unwrap().to_str().unwrap();
        assert_eq!(warning.contains(name), [1, 5, 10].contains(&i), "{name}: {warning}");
    }
}

/// The photograph as a JPEG whose EXIF block names an "Acme X100 Pro" at `focal_mm`.
fn tagged(photo: &Path, focal_mm: u32, dir: &Path) -> PathBuf {
    let picture = grey(photo);
    let mut jpeg = Vec::new();
    let mut encoder = image::codecs::jpeg::JpegEncoder::new_with_quality(&mut jpeg, 95);
    encoder.set_exif_metadata(exif_block("Acme", "X100 Pro", focal_mm)).unwrap();
    encoder.write_image(picture.as_raw(), picture.width(), picture.height(), image::ExtendedColorType::L8).unwrap();
    let copy = dir.join(photo.file_name().unwrap());
    std::fs::write(&copy, jpeg).unwrap();
    copy
}

#[test]
fn pictures_from_different_cameras_are_refused_naming_them() {
    let tmp = tempfile::tempdir().unwrap();
    let photos = opencv_photographs();
    let mut inputs: Vec<PathBuf> = photos.iter().map(|p| tagged(p, 35, tmp.path())).collect();
    let output = tmp.path().join("camera.json");
    let args = |inputs: &[PathBuf]| -> Vec<String> {
        let mut args: Vec<String> =
            ["calibrate", "--board", "chessboard", "--squares", "10x7", "-o", s(&output)].map(String::from).to_vec();
        args.extend(inputs.iter().map(|p| s(p).to_string()));
        args
    };
    let run = |inputs: &[PathBuf], expect: fn(&[&str]) -> String| {
        expect(&args(inputs).iter().map(String::as_str).collect::<Vec<_>>())
    };
    assert!(run(&inputs, ok).contains("13 images"));

    // One picture at another focal length: refused, naming it and its camera.
    inputs[7] = tagged(&photos[7], 50, tmp.path());
    let err = run(&inputs, fails);
    assert!(err.contains("different cameras") && err.contains("left08.jpg is from Acme X100 Pro 50 mm"), "{err}");
}
