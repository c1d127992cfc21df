//! `rmvp stokes I0 I45 I90 I135 -o DIR`.

use anyhow::Result;
use rmvp_capture::pipeline::write_polarization;
use rmvp_dataset::io::read_linear;
use rmvp_dataset::Stokes;
use std::path::PathBuf;

/// Arguments of `rmvp stokes`.
#[derive(clap::Args)]
pub struct Args {
    /// Linear images behind polarizers at 0, 45, 90 and 135 degrees (PNG 8/16-bit or EXR).
    #[arg(num_args = 4, required = true, value_names = ["I0", "I45", "I90", "I135"])]
    images: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
    /// Prefix of the output files.
    #[arg(long, default_value = "view")]
    stem: String,
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let images = args.images.iter().map(|p| read_linear(p)).collect::<Result<Vec<_>, _>>()?;
    let stokes = Stokes::from_polarizer_images([&images[0], &images[1], &images[2], &images[3]])?;
    let (aop, dop) = stokes.aop_dop();
    for path in write_polarization(&args.output, &args.stem, &stokes, &aop, &dop)? {
        println!("{}", path.display());
    }
    Ok(())
}
