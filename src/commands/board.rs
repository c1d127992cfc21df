//! `rmvp board -o board.png`: the calibration board as a page to print; and the board's
//! arguments, shared by every command that uses a board.

use anyhow::Result;
use rmvp_calib::board::{write_printable, Board, BoardKind, BoardOptions, Paper};
use std::path::PathBuf;

/// The printed board (defaults: the lab's board, [`BoardOptions::default`]).
#[derive(clap::Args, Clone, Debug)]
pub struct BoardArgs {
    /// Board kind.
    #[arg(long = "board", value_enum, default_value_t = BoardOptions::default().kind)]
    pub kind: BoardKind,
    /// Squares along x and y, `XxY`.
    #[arg(long, default_value_t = super::Pair(BoardOptions::default().squares[0], BoardOptions::default().squares[1]))]
    pub squares: super::Pair,
    /// Side of a square, millimetres.
    #[arg(long, default_value_t = BoardOptions::default().square_mm)]
    pub square_mm: f64,
    /// Side of a marker (ChArUco), millimetres.
    #[arg(long, default_value_t = BoardOptions::default().marker_mm)]
    pub marker_mm: f64,
    /// ArUco dictionary (ChArUco), OpenCV's name without `DICT_`.
    #[arg(long, default_value_t = BoardOptions::default().dictionary)]
    pub dictionary: String,
}

impl BoardArgs {
    /// The board described.
    pub fn spec(&self) -> BoardOptions {
        BoardOptions {
            kind: self.kind,
            squares: [self.squares.0, self.squares.1],
            square_mm: self.square_mm,
            marker_mm: self.marker_mm,
            dictionary: self.dictionary.clone(),
        }
    }
}

/// Arguments of `rmvp board`.
#[derive(clap::Args)]
pub struct Args {
    /// The page to print (PNG that states its resolution).
    #[arg(short, long, default_value = "board.png")]
    output: PathBuf,
    /// Print resolution, dots per inch.
    #[arg(long, default_value_t = Board::PAGE_DPI)]
    dpi: f64,
    /// White margin around the board, millimetres.
    #[arg(long, default_value_t = Board::PAGE_MARGIN_MM)]
    margin_mm: f64,
    /// The paper it will be printed on (a page that does not fit is written with a warning).
    #[arg(long, value_enum, default_value_t = Paper::default())]
    paper: Paper,
    /// The board.
    #[command(flatten)]
    board: BoardArgs,
}

/// Run `rmvp board`: write the board's page and say how to print it.
pub fn run(args: Args) -> Result<()> {
    let spec = args.board.spec();
    let board = Board::new(&spec)?;
    let page = board.printable(args.dpi, args.margin_mm)?;
    write_printable(&args.output, &page, args.dpi)?;
    let [w, h] = spec.size_mm();
    println!(
        "wrote {} ({}x{} px at {} dpi): a {:?} board of {}x{} squares, {w} x {h} mm",
        args.output.display(),
        page.width(),
        page.height(),
        args.dpi,
        spec.kind,
        spec.squares[0],
        spec.squares[1],
    );
    let [pw, ph] = board.page_mm(args.margin_mm);
    if !args.paper.holds([pw, ph]) {
        let [a, b] = args.paper.size_mm();
        eprintln!(
            "warning: the page is {pw:.0} x {ph:.0} mm and does not fit {:?} paper ({a} x {b} mm) either way up: \
             print it on larger paper (--paper), or choose fewer or smaller squares (--squares, --square-mm)",
            args.paper
        );
    }
    println!(
        "print it at 100 % (no fit to page), glue it flat, measure a square and pass that as --square-mm \
         (and the marker as --marker-mm) to calibrate and poses"
    );
    Ok(())
}
