//! A small RGB raster canvas for pictures of rollouts: filled circles, rings and thick
//! line segments with one-pixel anti-aliased edges, alpha-blended over what is there, and
//! PNG encoding (the `png` crate). A leaf like the rest of `report`. Coordinates are pixels, `(0, 0)` the top-left corner,
//! pixel `(i, j)` covering `[i, i+1) × [j, j+1)`.

/// An RGB colour, each channel 0–1.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Rgb(pub f32, pub f32, pub f32);

impl Rgb {
    pub const WHITE: Rgb = Rgb(1.0, 1.0, 1.0);
    pub const BLACK: Rgb = Rgb(0.0, 0.0, 0.0);

    /// The colour mixed with white: `amount` 0 keeps it, 1 gives white.
    pub fn lighten(self, amount: f32) -> Rgb {
        let m = |c: f32| c + (1.0 - c) * amount;
        Rgb(m(self.0), m(self.1), m(self.2))
    }

    /// The colour darkened: `amount` 0 keeps it, 1 gives black.
    pub fn darken(self, amount: f32) -> Rgb {
        let m = |c: f32| c * (1.0 - amount);
        Rgb(m(self.0), m(self.1), m(self.2))
    }
}

/// An RGB image in memory.
#[derive(Clone, Debug, PartialEq)]
pub struct Canvas {
    width: u32,
    height: u32,
    /// Row-major, 3 floats per pixel.
    pixels: Vec<f32>,
}

impl Canvas {
    /// A canvas filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgb) -> Canvas {
        let n = width as usize * height as usize;
        let mut pixels = Vec::with_capacity(3 * n);
        for _ in 0..n {
            pixels.extend_from_slice(&[background.0, background.1, background.2]);
        }
        Canvas {
            width,
            height,
            pixels,
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }

    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixel at `(x, y)` as 8-bit RGB (`None` outside the canvas).
    pub fn pixel(&self, x: u32, y: u32) -> Option<[u8; 3]> {
        (x < self.width && y < self.height).then(|| {
            let i = 3 * (y as usize * self.width as usize + x as usize);
            [
                to_u8(self.pixels[i]),
                to_u8(self.pixels[i + 1]),
                to_u8(self.pixels[i + 2]),
            ]
        })
    }

    /// Blends `colour` with opacity `alpha` (0–1) into the pixel at `(x, y)`, if inside.
    pub fn blend(&mut self, x: i64, y: i64, colour: Rgb, alpha: f32) {
        if x < 0 || y < 0 || x >= i64::from(self.width) || y >= i64::from(self.height) {
            return;
        }
        let a = alpha.clamp(0.0, 1.0);
        let i = 3 * (y as usize * self.width as usize + x as usize);
        for (k, c) in [colour.0, colour.1, colour.2].into_iter().enumerate() {
            let p = &mut self.pixels[i + k];
            *p += (c - *p) * a;
        }
    }

    /// Fills every pixel whose centre has `coverage(cx, cy) > 0`, blending with opacity
    /// `alpha · coverage`, over the pixel box `[x0, x1] × [y0, y1]`.
    fn fill_where(
        &mut self,
        (x0, y0, x1, y1): (f64, f64, f64, f64),
        colour: Rgb,
        alpha: f32,
        coverage: impl Fn(f64, f64) -> f64,
    ) {
        let (w, h) = (f64::from(self.width), f64::from(self.height));
        let clamp = |v: f64, max: f64| v.floor().clamp(0.0, max) as i64;
        let (xs, xe) = (clamp(x0 - 1.0, w), clamp(x1 + 2.0, w));
        for y in clamp(y0 - 1.0, h)..clamp(y1 + 2.0, h) {
            for x in xs..xe {
                let c = coverage(x as f64 + 0.5, y as f64 + 0.5);
                if c > 0.0 {
                    self.blend(x, y, colour, alpha * c.min(1.0) as f32);
                }
            }
        }
    }

    /// A filled disc of radius `r` around `(cx, cy)`.
    pub fn disc(&mut self, cx: f64, cy: f64, r: f64, colour: Rgb, alpha: f32) {
        self.fill_where((cx - r, cy - r, cx + r, cy + r), colour, alpha, |x, y| {
            edge(r - (x - cx).hypot(y - cy))
        });
    }

    /// A ring of radius `r` (to the middle of its stroke) and stroke width `width`.
    pub fn ring(&mut self, cx: f64, cy: f64, r: f64, width: f64, colour: Rgb, alpha: f32) {
        let outer = r + width / 2.0;
        self.fill_where(
            (cx - outer, cy - outer, cx + outer, cy + outer),
            colour,
            alpha,
            |x, y| edge(width / 2.0 - ((x - cx).hypot(y - cy) - r).abs()),
        );
    }

    /// A segment of stroke width `width` with round ends.
    pub fn line(
        &mut self,
        (x0, y0): (f64, f64),
        (x1, y1): (f64, f64),
        width: f64,
        colour: Rgb,
        alpha: f32,
    ) {
        let h = width / 2.0;
        let (dx, dy) = (x1 - x0, y1 - y0);
        let len2 = dx * dx + dy * dy;
        self.fill_where(
            (
                x0.min(x1) - h,
                y0.min(y1) - h,
                x0.max(x1) + h,
                y0.max(y1) + h,
            ),
            colour,
            alpha,
            |x, y| {
                let t = if len2 > 0.0 {
                    (((x - x0) * dx + (y - y0) * dy) / len2).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                edge(h - (x - (x0 + t * dx)).hypot(y - (y0 + t * dy)))
            },
        );
    }

    /// An axis-aligned filled rectangle `[x0, x1) × [y0, y1)` (whole pixels).
    pub fn rect(&mut self, x0: i64, y0: i64, x1: i64, y1: i64, colour: Rgb, alpha: f32) {
        for y in y0..y1 {
            for x in x0..x1 {
                self.blend(x, y, colour, alpha);
            }
        }
    }

    /// The image as a PNG file (8-bit RGB).
    pub fn to_png(&self) -> Result<Vec<u8>, png::EncodingError> {
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, self.width, self.height);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            let mut writer = encoder.write_header()?;
            let bytes: Vec<u8> = self.pixels.iter().map(|&c| to_u8(c)).collect();
            writer.write_image_data(&bytes)?;
            writer.finish()?;
        }
        Ok(out)
    }
}

/// Coverage of a pixel whose centre is `d` pixels inside a shape's edge (one-pixel ramp).
fn edge(d: f64) -> f64 {
    (d + 0.5).clamp(0.0, 1.0)
}

fn to_u8(c: f32) -> u8 {
    (c.clamp(0.0, 1.0) * 255.0).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shapes_cover_their_pixels_and_png_round_trips() {
        let mut c = Canvas::new(40, 30, Rgb::WHITE);
        c.disc(10.0, 10.0, 5.0, Rgb(1.0, 0.0, 0.0), 1.0);
        c.line((20.0, 20.0), (35.0, 20.0), 3.0, Rgb::BLACK, 1.0);
        assert_eq!(c.pixel(10, 10), Some([255, 0, 0]));
        assert_eq!(c.pixel(25, 19), Some([0, 0, 0]));
        assert_eq!(c.pixel(2, 25), Some([255, 255, 255]));
        assert_eq!(c.pixel(40, 0), None);
        let bytes = c.to_png().unwrap();
        let decoder = png::Decoder::new(std::io::Cursor::new(bytes));
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (40, 30));
        let at = |x: usize, y: usize| &buf[3 * (y * 40 + x)..3 * (y * 40 + x) + 3];
        assert_eq!(at(10, 10), [255, 0, 0]);
        assert_eq!(at(25, 19), [0, 0, 0]);
    }
}
