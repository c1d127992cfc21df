//! Boards against known answers: the board rendered by rmvp-render from known cameras is found
//! where those cameras project its corners (the pixel convention), and calibration from the
//! renders recovers the cameras' intrinsics; bad sets are refused by kind.

use nalgebra::{Matrix3, Vector3};
use rmvp_calib::board::{Board, BoardKind, BoardOptions};
use rmvp_calib::intrinsics::{calibrate, CalibrationOptions};
use rmvp_calib::lab::calibration_cameras;
use rmvp_calib::Error;
use rmvp_dataset::visualize::preview;
use rmvp_dataset::{Camera, Image};
use rmvp_render::pbrdf::{Interface, Lobes};
use rmvp_render::rig::look_at;
use rmvp_render::{render_view, EnvMap, Object, Part, Settings};

const SIZE: (u32, u32) = (640, 512);

fn intrinsics() -> Matrix3<f64> {
    Matrix3::new(900.0, 0.0, 322.5, 0.0, 900.0, 251.0, 0.0, 0.0, 1.0)
}

fn board_object(board: &Board) -> Object {
    let part = Part {
        mesh: board.plane_mesh(),
        interface: Interface::Dielectric(1.5),
        lobes: Lobes::Lambertian,
        texture: Some(board.albedo_texture(8.0).unwrap()),
        subject: true,
    };
    Object::from_parts(vec![part]).unwrap()
}

/// A camera `distance` mm from the board centre, seen from azimuth/elevation (degrees), turned
/// about its axis by `roll` degrees, looking `aside` mm beside the centre (so that the board
/// lands elsewhere in the frame).
fn camera(spec: &BoardOptions, azimuth: f64, elevation: f64, distance: f64, roll: f64, aside: [f64; 2]) -> Camera {
    let [w, h] = spec.size_mm();
    let centre = Vector3::new(w / 2.0, h / 2.0, 0.0);
    let (a, e) = (azimuth.to_radians(), elevation.to_radians());
    let eye = centre + distance * Vector3::new(e.cos() * a.cos(), e.cos() * a.sin(), e.sin());
    let up = Vector3::new(-roll.to_radians().sin(), roll.to_radians().cos(), 0.0);
    look_at(intrinsics(), eye, centre + Vector3::new(aside[0], aside[1], 0.0), up, SIZE.0, SIZE.1)
}

fn render(object: &Object, camera: &Camera, view: u32) -> Image<u8> {
    let env = EnvMap::uniform([1.0; 3]);
    let r = render_view(object, &env, camera, Settings { spp: 16, seed: rmvp_testkit::test_seed() }, view);
    preview(&r.stokes.s0)
}

fn cameras(spec: &BoardOptions) -> Vec<Camera> {
    calibration_cameras(spec, 24, intrinsics(), SIZE.0, SIZE.1, 0)
}

#[test]
fn rendered_boards_are_found_where_cameras_project_them_and_calibrate() {
    let spec = BoardOptions::default();
    let board = Board::new(&spec).unwrap();
    let object = board_object(&board);
    let cams = cameras(&spec);
    let images: Vec<(String, Image<u8>)> =
        cams.iter().enumerate().map(|(i, c)| (format!("{i:03}"), render(&object, c, i as u32))).collect();
    let (mut errors, mut total) = (Vec::new(), nalgebra::Vector2::zeros());
    for ((name, image), cam) in images.iter().zip(&cams) {
        let found = board.detect(image).unwrap();
        assert!(found.len() >= 20, "{name}: {} corners", found.len());
        let mut mean = nalgebra::Vector2::zeros();
        for (pixel, point) in found.pixels.iter().zip(&found.points) {
            errors.push((cam.project(point).unwrap() - pixel).norm());
            mean += cam.project(point).unwrap() - pixel;
        }
        // Steep views keep a small bias (the refinement window is square, the corner is not).
        let bias = (mean / found.len() as f64).norm();
        assert!(bias < 0.25, "{name}: corners off by {bias:.3} px on average");
        total += mean;
    }
    // No bias over all views: half a pixel would be a pixel-convention error (OpenCV 4.6's
    // ChArUco corners are half a pixel off without the sub-pixel refinement).
    let bias = (total / errors.len() as f64).norm();
    assert!(bias < 0.05, "corners off by {bias:.3} px on average");
    errors.sort_by(f64::total_cmp);
    let (median, p95) = (errors[errors.len() / 2], errors[errors.len() * 95 / 100]);
    eprintln!("corner error: median {median:.3} px, p95 {p95:.3} px over {}", errors.len());
    // Rendering noise (4 samples per pixel, 8-bit pictures); a flipped board frame is far off.
    assert!(median < 0.3 && p95 < 0.7, "median {median:.3} px, p95 {p95:.3} px");

    let run = calibrate(&images, &board, &CalibrationOptions::default()).unwrap();
    let k = run.calibration.k();
    let truth = intrinsics();
    eprintln!("calibrated K {k}, deviations {:?}, RMS {:.3} px", run.calibration.k_std_px, run.calibration.rms_px);
    assert!((k[(0, 0)] / truth[(0, 0)] - 1.0).abs() < 0.005 && (k[(1, 1)] / truth[(1, 1)] - 1.0).abs() < 0.005);
    assert!((k[(0, 2)] - truth[(0, 2)]).abs() < 1.0 && (k[(1, 2)] - truth[(1, 2)]).abs() < 1.0);
    // The calibration's own deviations are small and cover the truth.
    let std = run.calibration.k_std_px;
    assert!(std.iter().all(|&s| s < 1.5), "{std:?}");
    assert!((k[(0, 0)] - truth[(0, 0)]).abs() < 3.0 * std[0] && (k[(1, 2)] - truth[(1, 2)]).abs() < 3.0 * std[3]);
    assert!(run.calibration.rms_px < 0.4 && run.calibration.images.len() == 24, "{:?}", run.calibration);

    // The same board seen from one direction only, turned about the camera axis: the focal
    // length is not determined, and calibration says so, naming the images.
    let flat: Vec<(String, Image<u8>)> = [0.0, 40.0, 80.0, 120.0, 160.0]
        .iter()
        .enumerate()
        .map(|(i, &roll)| {
            (format!("flat{i}"), render(&object, &camera(&spec, 0.0, 90.0, 450.0, roll, [0.0; 2]), i as u32))
        })
        .collect();
    let err = calibrate(&flat, &board, &CalibrationOptions::default()).err().unwrap();
    assert!(matches!(&err, Error::Degenerate { images, .. } if images.contains("flat3")), "{err}");

    // Mixed sizes and boardless images are refused, naming the images.
    let mut mixed = images.clone();
    mixed[2].1 = Image::new(320, 256, 1);
    let err = calibrate(&mixed, &board, &CalibrationOptions::default()).err().unwrap();
    assert!(matches!(&err, Error::MixedSizes(text) if text.contains("002 is 320x256")), "{err}");
    let mut blank = images[..4].to_vec();
    blank[1].1 = Image::new(SIZE.0 as usize, SIZE.1 as usize, 1);
    let err = calibrate(&blank, &board, &CalibrationOptions::default()).err().unwrap();
    assert!(
        matches!(&err, Error::TooFewImages { usable: 3, rejected, .. } if rejected.contains("001 (0 corners")),
        "{err}"
    );
}

#[test]
fn a_chessboard_calibrates_too() {
    let spec = BoardOptions { kind: BoardKind::Chessboard, squares: [9, 7], ..BoardOptions::default() };
    let board = Board::new(&spec).unwrap();
    let object = board_object(&board);
    // Every other view of the set (the whole pattern must be in view; some are not).
    let images: Vec<(String, Image<u8>)> = cameras(&spec)
        .iter()
        .enumerate()
        .step_by(2)
        .map(|(i, c)| (format!("{i:03}"), render(&object, c, i as u32)))
        .collect();
    let run = calibrate(&images, &board, &CalibrationOptions::default()).unwrap();
    eprintln!("chessboard: {} images used, {:?} left out", run.calibration.images.len(), run.calibration.rejected);
    let k = run.calibration.k();
    // Fewer images than the ChArUco test: the principal point within 2 px.
    assert!((k[(0, 0)] / 900.0 - 1.0).abs() < 0.005 && (k[(0, 2)] - 322.5).abs() < 2.0, "{k}");
    assert_eq!(run.calibration.images.len() + run.calibration.rejected.len(), 12);
    assert!(Board::new(&BoardOptions { dictionary: "9X9".into(), ..BoardOptions::default() }).is_err());
}

#[test]
fn the_printable_page_prints_at_true_size_and_its_corners_are_where_the_board_frame_says() {
    let spec = BoardOptions::default();
    let board = Board::new(&spec).unwrap();
    let (dpi, margin_mm) = (200.0, 10.0);
    let page = board.printable(dpi, margin_mm).unwrap();
    let px_per_mm = dpi / 25.4;
    let [w, h] = spec.size_mm();
    // Board and margins are each rounded to whole pixels: within a pixel of the true size.
    let (pw, ph) = page.size();
    assert!(
        (pw as f64 - (w + 20.0) * px_per_mm).abs() <= 1.0 && (ph as f64 - (h + 20.0) * px_per_mm).abs() <= 1.0,
        "{pw}x{ph}"
    );
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("board.png");
    rmvp_calib::board::write_printable(&path, &page, dpi).unwrap();
    let stated = rmvp_dataset::io::png::read_png_dpi(&path).unwrap().unwrap();
    assert!((stated - dpi).abs() < 0.01, "{stated} dpi");
    // The page scanned flat: every corner found sits at its board coordinates (x right,
    // y up from the lower-left corner of the printed board).
    let found = board.detect(&page).unwrap();
    assert_eq!(found.len(), 35);
    let margin = margin_mm * px_per_mm;
    for (pixel, point) in found.pixels.iter().zip(&found.points) {
        let (x, y) = ((pixel.x - margin) / px_per_mm, h - (pixel.y - margin) / px_per_mm);
        // Squares and margins are drawn on whole pixels: within one pixel (0.127 mm here).
        let tolerance = 1.0 / px_per_mm;
        assert!((x - point.x).abs() < tolerance && (y - point.y).abs() < tolerance, "{pixel} vs {point}");
    }
    assert!(board.printable(10.0, 5.0).is_err());
    // The board's parameters are printed in the bottom margin, and only there.
    let margin_px = margin.round() as usize;
    let dark_rows: Vec<usize> = (0..ph).filter(|&y| (0..pw).any(|x| page.pixel(x, y)[0] < 128)).collect();
    let below_board = dark_rows.iter().filter(|&&y| y >= ph - margin_px).count();
    assert!(below_board > 5, "no label in the bottom margin");
    assert!(dark_rows.iter().all(|&y| y >= margin_px), "print in the top margin");
    let small = board.printable(dpi, 3.0).unwrap();
    let narrow = (3.0 * px_per_mm).floor() as usize;
    let bottom = small.height() - narrow..small.height();
    assert!(bottom.flat_map(|y| (0..small.width()).map(move |x| (x, y))).all(|(x, y)| small.pixel(x, y)[0] == 255));
}
