//! The calibration board's arguments, shared by every command that uses a board.

use rmvp_calib::board::{BoardKind, BoardSpec};

/// The printed board (defaults: the lab's ChArUco 8x6, 30 mm squares, 22 mm markers, 5X5_1000).
#[derive(clap::Args, Clone, Debug)]
pub struct BoardArgs {
    /// Board kind.
    #[arg(long = "board", value_enum, default_value_t = BoardSpec::default().kind)]
    pub kind: BoardKind,
    /// Squares along x and y, `XxY`.
    #[arg(long, value_parser = parse_squares, default_value = "8x6")]
    pub squares: [u32; 2],
    /// Side of a square, millimetres.
    #[arg(long, default_value_t = BoardSpec::default().square_mm)]
    pub square_mm: f64,
    /// Side of a marker (ChArUco), millimetres.
    #[arg(long, default_value_t = BoardSpec::default().marker_mm)]
    pub marker_mm: f64,
    /// ArUco dictionary (ChArUco), OpenCV's name without `DICT_`.
    #[arg(long, default_value_t = BoardSpec::default().dictionary)]
    pub dictionary: String,
}

fn parse_squares(text: &str) -> Result<[u32; 2], String> {
    let (x, y) = super::parse_size(text)?;
    Ok([x, y])
}

impl BoardArgs {
    /// The board described.
    pub fn spec(&self) -> BoardSpec {
        BoardSpec {
            kind: self.kind,
            squares: self.squares,
            square_mm: self.square_mm,
            marker_mm: self.marker_mm,
            dictionary: self.dictionary.clone(),
        }
    }
}
