//! A grouped bar chart as an RGB picture: one group per dataset, one bar per variant (its
//! mean) with a whisker for the spread over seeds, a labelled axis and a legend. Text is drawn
//! with the public-domain 8x8 bitmap font of `font8x8` (no font files, no system libraries).

use rmvp_dataset::Image;

/// One bar: a mean and its spread (standard deviation over seeds).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Bar {
    /// Height.
    pub mean: f64,
    /// Whisker half-length.
    pub spread: f64,
}

/// Bar colours, one per variant (cycled).
const PALETTE: [[u8; 3]; 6] =
    [[31, 119, 180], [255, 127, 14], [44, 160, 44], [214, 39, 40], [148, 103, 189], [140, 86, 75]];
const INK: [u8; 3] = [30, 30, 30];
const GRID: [u8; 3] = [225, 225, 225];
/// Pixels per font pixel.
const TEXT_SCALE: usize = 2;
const GLYPH: usize = 8 * TEXT_SCALE;

struct Canvas(Image<u8>);

impl Canvas {
    fn fill(&mut self, x0: usize, y0: usize, x1: usize, y1: usize, colour: [u8; 3]) {
        let (w, h) = self.0.size();
        for y in y0.min(h)..y1.min(h) {
            for x in x0.min(w)..x1.min(w) {
                self.0.pixel_mut(x, y).copy_from_slice(&colour);
            }
        }
    }

    /// Text with its top-left corner at (x, y); characters outside ASCII print as `?`.
    fn text(&mut self, x: usize, y: usize, text: &str, colour: [u8; 3]) {
        for (k, c) in text.chars().enumerate() {
            let code = if c.is_ascii() { c as usize } else { '?' as usize };
            let glyph = font8x8::legacy::BASIC_LEGACY[code];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..8 {
                    if bits >> col & 1 == 1 {
                        let (px, py) = (x + (k * 8 + col) * TEXT_SCALE, y + row * TEXT_SCALE);
                        self.fill(px, py, px + TEXT_SCALE, py + TEXT_SCALE, colour);
                    }
                }
            }
        }
    }
}

/// Text width in pixels.
fn text_width(text: &str) -> usize {
    text.chars().count() * GLYPH
}

/// A "nice" axis step (1, 2 or 5 times a power of ten) giving about five ticks up to `top`.
fn tick_step(top: f64) -> f64 {
    let raw = (top / 5.0).max(f64::MIN_POSITIVE);
    let power = 10f64.powf(raw.log10().floor());
    [1.0, 2.0, 5.0, 10.0].into_iter().map(|m| m * power).find(|&s| s >= raw).unwrap_or(10.0 * power)
}

/// Draw `bars[group][series]` (`None`: no result) with group and series labels and a title.
pub fn bar_chart(title: &str, groups: &[String], series: &[String], bars: &[Vec<Option<Bar>>]) -> Image<u8> {
    let bar_width = 28;
    let group_gap = 36;
    let group_width = series.len().max(1) * bar_width;
    let longest = series.iter().map(|s| text_width(s)).max().unwrap_or(0);
    let (left, top, plot_height) = (8 * GLYPH, 3 * GLYPH, 320);
    let legend_width = GLYPH * 2 + longest + GLYPH;
    let plot_width = groups.len().max(1) * (group_width + group_gap) + group_gap;
    let group_label = groups.iter().map(|g| text_width(g)).max().unwrap_or(0);
    // Group labels longer than their group are written on several rows, staggered.
    let label_rows = if group_label > group_width + group_gap { 2 } else { 1 };
    let width = (left + plot_width + GLYPH + legend_width).max(text_width(title) + 2 * GLYPH);
    let height = top + plot_height + GLYPH * (label_rows + 2);
    let mut canvas = Canvas(Image::new(width, height, 3));
    canvas.fill(0, 0, width, height, [255, 255, 255]);
    canvas.text(GLYPH, GLYPH / 2, title, INK);

    let highest = bars.iter().flatten().flatten().map(|b| b.mean + b.spread.max(0.0)).fold(0.0f64, f64::max);
    let step = tick_step(if highest > 0.0 { highest } else { 1.0 });
    let axis_top = (highest / step).ceil().max(1.0) * step;
    let y_of = |value: f64| top + plot_height - ((value / axis_top).clamp(0.0, 1.0) * plot_height as f64) as usize;
    let mut tick = 0.0;
    while tick <= axis_top + step * 1e-6 {
        let y = y_of(tick);
        canvas.fill(left, y, left + plot_width, y + 1, GRID);
        let label = if step >= 1.0 { format!("{tick:.0}") } else { format!("{tick:.prec$}", prec = 2) };
        canvas.text(left - text_width(&label) - GLYPH / 2, y.saturating_sub(GLYPH / 2), &label, INK);
        tick += step;
    }
    canvas.fill(left, top, left + 2, top + plot_height + 1, INK);
    canvas.fill(left, top + plot_height, left + plot_width, top + plot_height + 2, INK);

    for (g, name) in groups.iter().enumerate() {
        let x0 = left + group_gap + g * (group_width + group_gap);
        for (s, bar) in bars.get(g).into_iter().flatten().enumerate() {
            let Some(bar) = bar else { continue };
            let colour = PALETTE[s % PALETTE.len()];
            let x = x0 + s * bar_width;
            canvas.fill(x + 2, y_of(bar.mean), x + bar_width - 2, top + plot_height, colour);
            if bar.spread > 0.0 {
                let (hi, lo) = (y_of(bar.mean + bar.spread), y_of((bar.mean - bar.spread).max(0.0)));
                let mid = x + bar_width / 2;
                canvas.fill(mid - 1, hi, mid + 1, lo + 1, INK);
                canvas.fill(mid - 5, hi, mid + 5, hi + 2, INK);
                canvas.fill(mid - 5, lo, mid + 5, lo + 2, INK);
            }
        }
        let row = if label_rows > 1 { g % 2 } else { 0 };
        let label_x = (x0 + group_width / 2).saturating_sub(text_width(name) / 2);
        canvas.text(label_x, top + plot_height + GLYPH / 2 + row * GLYPH, name, INK);
    }

    let legend_x = left + plot_width + GLYPH;
    for (s, name) in series.iter().enumerate() {
        let y = top + s * (GLYPH + 6);
        canvas.fill(legend_x, y, legend_x + GLYPH, y + GLYPH, PALETTE[s % PALETTE.len()]);
        canvas.text(legend_x + GLYPH + GLYPH / 2, y, name, INK);
    }
    canvas.0
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_are_one_two_or_five_times_a_power_of_ten() {
        assert_eq!(tick_step(10.0), 2.0);
        assert_eq!(tick_step(23.0), 5.0);
        assert!((tick_step(0.07) - 0.02).abs() < 1e-12);
    }

    #[test]
    fn bars_are_as_tall_as_their_means_in_their_colours() {
        let bars = vec![vec![Some(Bar { mean: 10.0, spread: 0.0 }), Some(Bar { mean: 5.0, spread: 1.0 })]];
        let image = bar_chart("normal MAE", &["spot".into()], &["full".into(), "no-geo".into()], &bars);
        // Count the pixels of each series' colour in the plot: the first bar is twice as tall.
        let count = |colour: [u8; 3]| {
            (0..image.width()).map(|x| (0..image.height()).filter(|&y| image.pixel(x, y) == colour).count()).max()
        };
        let (first, second) = (count(PALETTE[0]).unwrap(), count(PALETTE[1]).unwrap());
        // Each bar column's height (the legend swatch adds GLYPH pixels to one column at most).
        assert!((first as f64 / second as f64 - 2.0).abs() < 0.05, "{first} vs {second}");
    }
}
