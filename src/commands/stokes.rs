//! `rmvp stokes I0 I45 I90 I135 -o DIR`.

use anyhow::{bail, Result};
use rmvp_capture::pipeline::write_polarization;
use rmvp_dataset::io::{exr, png};
use rmvp_dataset::polarization::stokes_from_four;
use rmvp_dataset::{Image, Stokes};
use std::path::{Path, PathBuf};

/// Arguments of `rmvp stokes`.
#[derive(clap::Args)]
pub struct Args {
    /// Linear images behind polarizers at 0, 45, 90 and 135 degrees (PNG 8/16-bit or EXR).
    #[arg(num_args = 4, required = true)]
    images: Vec<PathBuf>,
    /// Output folder.
    #[arg(short, long)]
    output: PathBuf,
    /// Prefix of the output files.
    #[arg(long, default_value = "view")]
    stem: String,
}

/// A linear image: PNG samples divided by their full scale, EXR `R G B` or its only channel.
fn read_linear(path: &Path) -> Result<Image<f32>> {
    let is_exr = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("exr"));
    Ok(if is_exr {
        let (_, _, channels) = exr::read_exr_channels(path)?;
        let names: Vec<&str> = channels.iter().map(|(n, _)| n.as_str()).collect();
        if ["R", "G", "B"].iter().all(|c| names.contains(c)) {
            exr::read_exr(path, &["R", "G", "B"])?
        } else if names.len() == 1 {
            exr::read_exr(path, &[names[0]])?
        } else {
            bail!("{}: expected channels R, G, B or a single channel, found {names:?}", path.display());
        }
    } else {
        match png::read_png(path)? {
            png::PngImage::U8(i) => i.map(|v| v as f32 / 255.0),
            png::PngImage::U16(i) => i.map(|v| v as f32 / 65535.0),
        }
    })
}

/// Run the command.
pub fn run(args: Args) -> Result<()> {
    let images = args.images.iter().map(|p| read_linear(p)).collect::<Result<Vec<_>>>()?;
    for (image, path) in images.iter().zip(&args.images).skip(1) {
        if image.size() != images[0].size() || image.channels() != images[0].channels() {
            bail!(
                "{}: {}x{}x{} differs from {} ({}x{}x{})",
                path.display(),
                image.width(),
                image.height(),
                image.channels(),
                args.images[0].display(),
                images[0].width(),
                images[0].height(),
                images[0].channels()
            );
        }
    }
    let (w, h, c) = (images[0].width(), images[0].height(), images[0].channels());
    let mut s = [Image::new(w, h, c), Image::new(w, h, c), Image::new(w, h, c)];
    for k in 0..w * h * c {
        let v = stokes_from_four([0, 1, 2, 3].map(|a| images[a].data()[k]));
        for (component, value) in s.iter_mut().zip(v) {
            component.data_mut()[k] = value;
        }
    }
    let [s0, s1, s2] = s;
    let stokes = Stokes { s0, s1, s2 };
    let (aop, dop) = stokes.aop_dop();
    for path in write_polarization(&args.output, &args.stem, &stokes, &aop, &dop)? {
        println!("{}", path.display());
    }
    Ok(())
}
