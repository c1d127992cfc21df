//! Calibration boards (OpenCV 4.6, the contrib `aruco` module): their description, their
//! picture for printing or rendering, and the detection of their corners in an image.
//!
//! The board frame is rmvp's world frame whenever a board gives the poses: origin at the corner
//! of the printed board that is lower-left when its picture is upright, x along the first
//! (longer) side, y along the other, z up out of the printed face, millimetres. OpenCV 4.6
//! puts its board origin at the upper-left with y down the picture and z into the board; the
//! conversion is made here, once. Detected corners are in rmvp's pixel convention (pixel
//! `(i, j)` centred at `(i + 0.5, j + 0.5)`), OpenCV's plus half a pixel.

use crate::{Error, Result};
use nalgebra::{Matrix3, Point2, Point3, Vector2};
use opencv::core::{self, Mat, Point2f, Ptr, Vector};
use opencv::prelude::*;
use opencv::{aruco, calib3d, imgproc};
use rmvp_dataset::mesh::{ScalarKind, VertexProperty};
use rmvp_dataset::{Image, Mesh};
use serde::{Deserialize, Serialize};

/// Paper sizes a board page is printed on.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum Paper {
    /// ISO A4, 210 x 297 mm.
    #[default]
    A4,
    /// ISO A3, 297 x 420 mm.
    A3,
    /// US Letter, 215.9 x 279.4 mm.
    Letter,
}

impl Paper {
    /// Width and height, millimetres (portrait).
    pub fn size_mm(self) -> [f64; 2] {
        match self {
            Paper::A4 => [210.0, 297.0],
            Paper::A3 => [297.0, 420.0],
            Paper::Letter => [215.9, 279.4],
        }
    }

    /// Whether a page of `page_mm` (width, height) fits on this paper, upright or turned.
    pub fn holds(self, page_mm: [f64; 2]) -> bool {
        let [a, b] = self.size_mm();
        let [w, h] = page_mm;
        (w <= a && h <= b) || (w <= b && h <= a)
    }
}

/// The least margin (millimetres) that carries the board's parameters in print.
pub const LABEL_MARGIN_MM: f64 = 6.0;

/// The two kinds of board.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "clap", derive(clap::ValueEnum))]
#[serde(rename_all = "lowercase")]
pub enum BoardKind {
    /// A chessboard with ArUco markers in its white squares: corners are identified, so any
    /// part of the board will do (intrinsics and poses).
    #[default]
    Charuco,
    /// A plain chessboard: the whole pattern must be seen (intrinsics only).
    Chessboard,
}

/// The ArUco dictionaries of OpenCV 4.6, by their OpenCV names without `DICT_` (`5X5_1000`).
pub const DICTIONARIES: [(&str, aruco::PREDEFINED_DICTIONARY_NAME); 17] = {
    use aruco::PREDEFINED_DICTIONARY_NAME::*;
    [
        ("4X4_50", DICT_4X4_50),
        ("4X4_100", DICT_4X4_100),
        ("4X4_250", DICT_4X4_250),
        ("4X4_1000", DICT_4X4_1000),
        ("5X5_50", DICT_5X5_50),
        ("5X5_100", DICT_5X5_100),
        ("5X5_250", DICT_5X5_250),
        ("5X5_1000", DICT_5X5_1000),
        ("6X6_50", DICT_6X6_50),
        ("6X6_100", DICT_6X6_100),
        ("6X6_250", DICT_6X6_250),
        ("6X6_1000", DICT_6X6_1000),
        ("7X7_50", DICT_7X7_50),
        ("7X7_100", DICT_7X7_100),
        ("7X7_250", DICT_7X7_250),
        ("7X7_1000", DICT_7X7_1000),
        ("ARUCO_ORIGINAL", DICT_ARUCO_ORIGINAL),
    ]
};

/// A calibration board as printed.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct BoardOptions {
    /// ChArUco or chessboard.
    pub kind: BoardKind,
    /// Squares along x and y.
    pub squares: [u32; 2],
    /// Side of a square, millimetres.
    pub square_mm: f64,
    /// Side of a marker (ChArUco), millimetres.
    pub marker_mm: f64,
    /// ArUco dictionary (ChArUco), e.g. `5X5_1000`.
    pub dictionary: String,
}

impl Default for BoardOptions {
    /// The lab's board: ChArUco 8x6 squares of 30 mm, 22 mm markers from `5X5_1000`.
    fn default() -> Self {
        Self {
            kind: BoardKind::Charuco,
            squares: [8, 6],
            square_mm: 30.0,
            marker_mm: 22.0,
            dictionary: "5X5_1000".into(),
        }
    }
}

impl BoardOptions {
    /// The board's extent in millimetres (x, y).
    pub fn size_mm(&self) -> [f64; 2] {
        [self.squares[0] as f64 * self.square_mm, self.squares[1] as f64 * self.square_mm]
    }

    /// The inner corners along x and y.
    pub fn inner_corners(&self) -> [u32; 2] {
        [self.squares[0] - 1, self.squares[1] - 1]
    }

    /// Check the numbers.
    pub fn validate(&self) -> Result<()> {
        let bad = |why: String| Err(Error::Board(why));
        if self.squares[0] < 3 || self.squares[1] < 3 {
            return bad(format!("{}x{} squares: at least 3x3", self.squares[0], self.squares[1]));
        }
        if self.square_mm.is_nan() || self.square_mm <= 0.0 {
            return bad(format!("square size {} mm", self.square_mm));
        }
        if self.kind == BoardKind::Charuco {
            if self.marker_mm.is_nan() || self.marker_mm <= 0.0 || self.marker_mm >= self.square_mm {
                return bad(format!(
                    "marker size {} mm must be below the square size {} mm",
                    self.marker_mm, self.square_mm
                ));
            }
            dictionary(&self.dictionary)?;
        }
        Ok(())
    }
}

fn dictionary(name: &str) -> Result<aruco::PREDEFINED_DICTIONARY_NAME> {
    let name = name.trim_start_matches("DICT_");
    DICTIONARIES.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, d)| *d).ok_or_else(|| {
        Error::Board(format!("unknown ArUco dictionary {name:?} (one of {})", DICTIONARIES.map(|(n, _)| n).join(", ")))
    })
}

/// The corners found in one image, with their board coordinates.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Detection {
    /// Corner identities (ChArUco corner ids; chessboard: row-major index).
    pub ids: Vec<u32>,
    /// Where they are in the image (rmvp pixel convention).
    pub pixels: Vec<Point2<f64>>,
    /// Where they are on the board (board frame, millimetres, z = 0).
    pub points: Vec<Point3<f64>>,
    /// ArUco markers found (ChArUco).
    pub markers: usize,
}

impl Detection {
    /// Corners found.
    pub fn len(&self) -> usize {
        self.ids.len()
    }

    /// True when nothing was found.
    pub fn is_empty(&self) -> bool {
        self.ids.is_empty()
    }
}

/// A board ready to draw and detect.
pub struct Board {
    spec: BoardOptions,
    charuco: Option<(Ptr<aruco::CharucoBoard>, Ptr<aruco::Dictionary>)>,
}

/// OpenCV's ChArUco board of `spec` and its dictionary.
fn charuco_board(spec: &BoardOptions) -> Result<(Ptr<aruco::CharucoBoard>, Ptr<aruco::Dictionary>)> {
    let dict = aruco::get_predefined_dictionary(dictionary(&spec.dictionary)?)?;
    let board = aruco::CharucoBoard::create(
        spec.squares[0] as i32,
        spec.squares[1] as i32,
        spec.square_mm as f32,
        spec.marker_mm as f32,
        &dict,
    )?;
    Ok((board, dict))
}

/// When `cornerSubPix` stops.
fn subpixel_criteria() -> Result<core::TermCriteria> {
    Ok(core::TermCriteria::new(core::TermCriteria_COUNT + core::TermCriteria_EPS, 50, 1e-4)?)
}

/// OpenCV's board coordinates to ours: x kept, y flipped about the board's height, z flipped.
fn from_opencv(spec: &BoardOptions, p: core::Point3f) -> Point3<f64> {
    Point3::new(p.x as f64, spec.size_mm()[1] - p.y as f64, -(p.z as f64))
}

/// Pixels as OpenCV 4.6 wants them: an 8-bit grey `Mat` over our image (copied; colour turned
/// grey by [`crate::pictures::grey_of_encoded`]).
fn grey_mat(image: &Image<u8>) -> Result<Mat> {
    let grey = crate::pictures::grey_of_encoded(image);
    let mat = Mat::from_slice(grey.data())?;
    Ok(mat.reshape(1, image.height() as i32)?.try_clone()?)
}

impl Board {
    /// The board of `spec`.
    pub fn new(spec: &BoardOptions) -> Result<Self> {
        spec.validate()?;
        let charuco = match spec.kind {
            BoardKind::Charuco => Some(charuco_board(spec)?),
            BoardKind::Chessboard => None,
        };
        Ok(Self { spec: spec.clone(), charuco })
    }

    /// The board's description.
    pub fn spec(&self) -> &BoardOptions {
        &self.spec
    }

    /// The board's picture at `px_per_mm` (8-bit grey, no margin), upright: its top row is the
    /// board's `y = height` edge, its left column `x = 0`.
    pub fn draw(&self, px_per_mm: f64) -> Result<Image<u8>> {
        let [w, h] = self.spec.size_mm().map(|v| (v * px_per_mm).round() as usize);
        let data = match &self.charuco {
            Some(_) => {
                // OpenCV's draw mutates its board: draw with a fresh one.
                let (mut board, _) = charuco_board(&self.spec)?;
                let mut mat = Mat::default();
                board.draw(core::Size::new(w as i32, h as i32), &mut mat, 0, 1)?;
                mat.data_bytes()?.to_vec()
            }
            None => {
                let square = self.spec.square_mm * px_per_mm;
                let mut data = vec![255u8; w * h];
                for (k, v) in data.iter_mut().enumerate() {
                    let (i, j) = ((k % w) as f64 / square, (k / w) as f64 / square);
                    if (i as u32 + j as u32).is_multiple_of(2) {
                        *v = 0;
                    }
                }
                data
            }
        };
        Ok(Image::from_vec(w, h, 1, data)?)
    }

    /// The page of [`Board::printable`] with a margin of `margin_mm`, millimetres (width, height).
    pub fn page_mm(&self, margin_mm: f64) -> [f64; 2] {
        self.spec.size_mm().map(|v| v + 2.0 * margin_mm)
    }

    /// The print resolution of a page unless told otherwise, dots per inch.
    pub const PAGE_DPI: f64 = 300.0;
    /// The white margin of a page unless told otherwise, millimetres.
    pub const PAGE_MARGIN_MM: f64 = 10.0;

    /// The board as a page to print: [`Board::draw`] at `dpi` with a white margin of
    /// `margin_mm` all round (detectors need a quiet zone beyond the outer squares), written by
    /// [`write_printable`] with its resolution so that it prints at its true size. A margin of
    /// [`LABEL_MARGIN_MM`] or more carries the board's parameters in small print along its
    /// bottom edge (away from the board, which keeps its quiet zone).
    pub fn printable(&self, dpi: f64, margin_mm: f64) -> Result<Image<u8>> {
        if !(dpi.is_finite() && dpi >= 50.0 && margin_mm.is_finite() && margin_mm >= 0.0) {
            return Err(Error::Board(format!("a page at {dpi} dpi with a {margin_mm} mm margin")));
        }
        let px_per_mm = dpi / 25.4;
        let board = self.draw(px_per_mm)?;
        let margin = (margin_mm * px_per_mm).round() as usize;
        let (w, h) = (board.width() + 2 * margin, board.height() + 2 * margin);
        let mut page = Image::from_vec(w, h, 1, vec![255u8; w * h])?;
        for y in 0..board.height() {
            let row = &board.data()[y * board.width()..(y + 1) * board.width()];
            let start = (y + margin) * w + margin;
            page.data_mut()[start..start + board.width()].copy_from_slice(row);
        }
        if margin_mm >= LABEL_MARGIN_MM {
            self.label(&mut page, margin)?;
        }
        Ok(page)
    }

    /// The board's parameters, as `calibrate` and `poses` need them, written in the bottom
    /// `margin` pixels of `page`.
    fn label(&self, page: &mut Image<u8>, margin: usize) -> Result<()> {
        let s = &self.spec;
        let text = match s.kind {
            BoardKind::Charuco => format!(
                "ChArUco {}x{} squares of {} mm, markers {} mm, {}. Print at 100 %.",
                s.squares[0], s.squares[1], s.square_mm, s.marker_mm, s.dictionary
            ),
            BoardKind::Chessboard => {
                format!("Chessboard {}x{} squares of {} mm. Print at 100 %.", s.squares[0], s.squares[1], s.square_mm)
            }
        };
        let (w, h) = page.size();
        let font = imgproc::FONT_HERSHEY_SIMPLEX;
        let mut baseline = 0;
        let unit = imgproc::get_text_size(&text, font, 1.0, 1, &mut baseline)?;
        // A third of the margin high, and no wider than the page less its margins.
        let scale = (margin as f64 / 3.0 / unit.height as f64).min((w - 2 * margin) as f64 / unit.width as f64);
        let thickness = ((scale * 1.5).round() as i32).max(1);
        let mut mat = Mat::new_rows_cols_with_data(h as i32, w as i32, page.data())?.try_clone()?;
        let origin = core::Point::new(margin as i32, (h - margin / 3) as i32);
        imgproc::put_text(
            &mut mat,
            &text,
            origin,
            font,
            scale,
            core::Scalar::all(0.0),
            thickness,
            imgproc::LINE_AA,
            false,
        )?;
        page.data_mut().copy_from_slice(mat.data_bytes()?);
        Ok(())
    }

    /// The printed board as a mesh: one quad in the board frame's `z = 0` plane with texture
    /// coordinates for [`Board::albedo_texture`] (for rendering a simulated lab).
    pub fn plane_mesh(&self) -> Mesh {
        let [w, h] = self.spec.size_mm().map(|v| v as f32);
        let corners = [[0.0, 0.0], [w, 0.0], [w, h], [0.0, h]];
        let property = |name: &str, axis: usize| VertexProperty {
            name: name.into(),
            kind: ScalarKind::F32,
            values: corners.iter().map(|c| (c[axis] / [w, h][axis]) as f64).collect(),
        };
        Mesh {
            positions: corners.iter().map(|c| [c[0], c[1], 0.0]).collect(),
            normals: Some(vec![[0.0, 0.0, 1.0]; 4]),
            faces: vec![[0, 1, 2], [0, 2, 3]],
            vertex_properties: vec![property("u", 0), property("v", 1)],
        }
    }

    /// The printed board's albedo for rendering: paper white 0.8, ink black 0.04 (linear RGB).
    pub fn albedo_texture(&self, px_per_mm: f64) -> Result<Image<f32>> {
        Ok(self.draw(px_per_mm)?.map(|v| 0.04 + 0.76 * v as f32 / 255.0).channel_to_rgb())
    }

    /// Find the board's corners in `image` (8-bit, grey or RGB). Nothing found is an empty
    /// detection, not an error.
    pub fn detect(&self, image: &Image<u8>) -> Result<Detection> {
        let mat = grey_mat(image)?;
        let mut found = match &self.charuco {
            Some((board, dict)) => self.detect_charuco(&mat, board, dict)?,
            None => self.detect_chessboard(&mat)?,
        };
        // OpenCV's pixel centres are at integers, ours at +0.5.
        found.pixels.iter_mut().for_each(|p| *p += Vector2::new(0.5, 0.5));
        Ok(found)
    }

    fn detect_charuco(
        &self,
        mat: &Mat,
        board: &Ptr<aruco::CharucoBoard>,
        dict: &Ptr<aruco::Dictionary>,
    ) -> Result<Detection> {
        let params = aruco::DetectorParameters::create()?;
        let mut marker_corners = Vector::<Vector<Point2f>>::new();
        let mut marker_ids = Vector::<i32>::new();
        let mut rejected = Vector::<Vector<Point2f>>::new();
        aruco::detect_markers(mat, dict, &mut marker_corners, &mut marker_ids, &params, &mut rejected)?;
        if marker_ids.is_empty() {
            return Ok(Detection::default());
        }
        let mut corners = Vector::<Point2f>::new();
        let mut ids = Vector::<i32>::new();
        aruco::interpolate_corners_charuco(
            &marker_corners,
            &marker_ids,
            mat,
            board,
            &mut corners,
            &mut ids,
            &core::no_array(),
            &core::no_array(),
            2,
        )?;
        // OpenCV 4.6 leaves the interpolated ChArUco corners half a pixel off its own convention
        // (measured on rendered boards); refining them as chessboard corners removes that.
        // The refinement window scales with the squares as seen (an eighth of a square's side,
        // from the markers' sides): smaller windows left corners of tilted views biased by up to
        // 0.2 px, larger ones reach neighbouring corners.
        if !corners.is_empty() {
            let marker_px: f64 = marker_corners
                .iter()
                .map(|m| {
                    let p: Vec<Point2f> = m.iter().collect();
                    (0..4).map(|k| ((p[k].x - p[(k + 1) % 4].x).hypot(p[k].y - p[(k + 1) % 4].y)) as f64).sum::<f64>()
                        / 4.0
                })
                .sum::<f64>()
                / marker_corners.len() as f64;
            let half = (0.12 * marker_px * self.spec.square_mm / self.spec.marker_mm).round().clamp(2.0, 12.0) as i32;
            imgproc::corner_sub_pix(
                mat,
                &mut corners,
                core::Size::new(half, half),
                core::Size::new(-1, -1),
                subpixel_criteria()?,
            )?;
        }
        let object = board.chessboard_corners();
        let mut detection = Detection { markers: marker_ids.len(), ..Detection::default() };
        for (id, p) in ids.iter().zip(corners.iter()) {
            detection.ids.push(id as u32);
            detection.pixels.push(Point2::new(p.x as f64, p.y as f64));
            detection.points.push(from_opencv(&self.spec, object.get(id as usize)?));
        }
        Ok(detection)
    }

    fn detect_chessboard(&self, mat: &Mat) -> Result<Detection> {
        let [nx, ny] = self.spec.inner_corners();
        let mut corners = Vector::<Point2f>::new();
        let flags = calib3d::CALIB_CB_ADAPTIVE_THRESH | calib3d::CALIB_CB_NORMALIZE_IMAGE;
        if !calib3d::find_chessboard_corners(mat, core::Size::new(nx as i32, ny as i32), &mut corners, flags)? {
            return Ok(Detection::default());
        }
        imgproc::corner_sub_pix(
            mat,
            &mut corners,
            core::Size::new(5, 5),
            core::Size::new(-1, -1),
            subpixel_criteria()?,
        )?;
        let mut detection = Detection::default();
        for (k, p) in corners.iter().enumerate() {
            let (i, j) = ((k as u32 % nx) as f64, (k as u32 / nx) as f64);
            let opencv = core::Point3f::new(
                ((i + 1.0) * self.spec.square_mm) as f32,
                ((j + 1.0) * self.spec.square_mm) as f32,
                0.0,
            );
            detection.ids.push(k as u32);
            detection.pixels.push(Point2::new(p.x as f64, p.y as f64));
            detection.points.push(from_opencv(&self.spec, opencv));
        }
        Ok(detection)
    }

    /// Whether the corners `ids` of a ChArUco board all lie on one line (no pose from them).
    pub fn collinear(&self, ids: &[u32]) -> Result<bool> {
        match &self.charuco {
            Some((board, _)) => {
                let ids: Vector<i32> = ids.iter().map(|&i| i as i32).collect();
                Ok(aruco::test_charuco_corners_collinear(board, &ids)?)
            }
            None => Ok(false),
        }
    }
}

/// The rotation from the board frame (z up) to a frame with +Y up and the board's y towards
/// -Z, the frame environment maps are stored in.
pub fn board_to_y_up() -> Matrix3<f64> {
    Matrix3::new(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, -1.0, 0.0)
}

/// Write `page` ([`Board::printable`]) as a PNG that states `dpi`, so that printing it at
/// 100 % gives squares of the specified size.
pub fn write_printable(path: &std::path::Path, page: &Image<u8>, dpi: f64) -> Result<()> {
    Ok(rmvp_dataset::io::png::write_png_u8_for_print(path, page, dpi)?)
}
