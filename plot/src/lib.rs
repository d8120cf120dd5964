//! rtconf-plot: small PNG charts for benchmarks and run reports — line and scatter plots and heat
//! maps with axes, ticks, a legend and text drawn by the crate itself (a 5×7 bitmap font of its
//! own), encoded with the `png` crate. No other dependency, no system fonts.
//!
//! ```no_run
//! use plot::{Axis, Chart, Marker, Scale, Series, Style, palette};
//! let chart = Chart {
//!     title: "time per ray".into(),
//!     x: Axis::new("mode", Scale::Linear),
//!     y: Axis::new("ns", Scale::Log10),
//!     series: vec![Series {
//!         name: "soup".into(),
//!         points: vec![(1.0, 300.0), (2.0, 900.0)],
//!         color: palette::series(0),
//!         style: Style::LineAndMarkers(Marker::Circle),
//!     }],
//!     legend: true,
//! };
//! chart.render(800, 600).write_png("target/example.png").unwrap();
//! ```

mod axis;
mod chart;
pub mod font;
mod heatmap;

pub use axis::{format_tick, ticks, Axis, Scale};
pub use chart::{Chart, Marker, Series, Style};
pub use heatmap::HeatMap;

use std::io;
use std::path::Path;

/// An 8-bit RGB colour.
pub type Rgb = [u8; 3];

/// Colours: distinguishable series colours and the chart's greys.
pub mod palette {
    use super::Rgb;

    pub const WHITE: Rgb = [255, 255, 255];
    pub const BLACK: Rgb = [0, 0, 0];
    pub const TEXT: Rgb = [30, 30, 30];
    pub const AXIS: Rgb = [60, 60, 60];
    pub const GRID: Rgb = [225, 225, 225];
    pub const MISSING: Rgb = [200, 200, 200];

    const SERIES: [Rgb; 8] = [
        [31, 106, 181],
        [222, 110, 20],
        [40, 150, 60],
        [200, 40, 40],
        [130, 80, 180],
        [140, 86, 75],
        [220, 100, 180],
        [100, 100, 100],
    ];

    /// The colour of series `i` (cycling through eight).
    pub fn series(i: usize) -> Rgb {
        SERIES[i % SERIES.len()]
    }

    /// A sequential colour map from dark blue through teal and green to yellow, `x` in [0, 1]
    /// (clamped); NaN gives [`MISSING`].
    pub fn sequential(x: f64) -> Rgb {
        const STOPS: [Rgb; 5] = [
            [40, 20, 90],
            [40, 80, 150],
            [30, 140, 140],
            [90, 190, 90],
            [245, 230, 60],
        ];
        if x.is_nan() {
            return MISSING;
        }
        let x = x.clamp(0.0, 1.0) * (STOPS.len() - 1) as f64;
        let i = (x.floor() as usize).min(STOPS.len() - 2);
        let f = x - i as f64;
        [0, 1, 2]
            .map(|k| (STOPS[i][k] as f64 * (1.0 - f) + STOPS[i + 1][k] as f64 * f).round() as u8)
    }
}

/// A pixel rectangle: left, top, width, height.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Rect {
    pub x: i32,
    pub y: i32,
    pub w: i32,
    pub h: i32,
}

impl Rect {
    pub fn new(x: i32, y: i32, w: i32, h: i32) -> Rect {
        Rect { x, y, w, h }
    }
    pub fn right(&self) -> i32 {
        self.x + self.w
    }
    pub fn bottom(&self) -> i32 {
        self.y + self.h
    }
    pub fn contains(&self, x: i32, y: i32) -> bool {
        x >= self.x && x < self.right() && y >= self.y && y < self.bottom()
    }
}

/// Where text is anchored horizontally.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Align {
    Left,
    Center,
    Right,
}

/// An RGB raster that charts draw into; (0, 0) is the top left.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Image {
    width: u32,
    height: u32,
    pixels: Vec<Rgb>,
}

impl Image {
    /// A `width`×`height` image filled with `background`.
    pub fn new(width: u32, height: u32, background: Rgb) -> Image {
        Image {
            width,
            height,
            pixels: vec![background; (width * height) as usize],
        }
    }

    pub fn width(&self) -> u32 {
        self.width
    }
    pub fn height(&self) -> u32 {
        self.height
    }

    /// The pixel at (x, y), `None` outside.
    pub fn get(&self, x: i32, y: i32) -> Option<Rgb> {
        self.index(x, y).map(|i| self.pixels[i])
    }

    fn index(&self, x: i32, y: i32) -> Option<usize> {
        (x >= 0 && y >= 0 && (x as u32) < self.width && (y as u32) < self.height)
            .then(|| (y as u32 * self.width + x as u32) as usize)
    }

    /// Sets a pixel; outside the image nothing happens.
    pub fn set(&mut self, x: i32, y: i32, c: Rgb) {
        if let Some(i) = self.index(x, y) {
            self.pixels[i] = c;
        }
    }

    pub fn fill_rect(&mut self, r: Rect, c: Rgb) {
        for y in r.y..r.bottom() {
            for x in r.x..r.right() {
                self.set(x, y, c);
            }
        }
    }

    /// The outline of a rectangle, one pixel wide.
    pub fn stroke_rect(&mut self, r: Rect, c: Rgb) {
        self.line(r.x, r.y, r.right() - 1, r.y, c, 1);
        self.line(r.x, r.bottom() - 1, r.right() - 1, r.bottom() - 1, c, 1);
        self.line(r.x, r.y, r.x, r.bottom() - 1, c, 1);
        self.line(r.right() - 1, r.y, r.right() - 1, r.bottom() - 1, c, 1);
    }

    /// A straight line (Bresenham) drawn with a square pen `width` pixels across.
    #[allow(clippy::too_many_arguments)]
    pub fn line(&mut self, x0: i32, y0: i32, x1: i32, y1: i32, c: Rgb, width: i32) {
        let (dx, dy) = ((x1 - x0).abs(), -(y1 - y0).abs());
        let (sx, sy) = (if x0 < x1 { 1 } else { -1 }, if y0 < y1 { 1 } else { -1 });
        let (mut x, mut y, mut err) = (x0, y0, dx + dy);
        let lo = -(width - 1) / 2;
        let hi = width / 2;
        // Long lines off-canvas are clipped by `set`; bound the walk all the same.
        for _ in 0..=(dx - dy).min(1 << 16) {
            for oy in lo..=hi {
                for ox in lo..=hi {
                    self.set(x + ox, y + oy, c);
                }
            }
            if x == x1 && y == y1 {
                break;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += sx;
            }
            if e2 <= dx {
                err += dx;
                y += sy;
            }
        }
    }

    /// Text whose top edge is at `y`, anchored at `x` as `align` says; returns its width.
    pub fn text(&mut self, x: i32, y: i32, text: &str, c: Rgb, scale: u32, align: Align) -> u32 {
        let w = font::text_width(text, scale);
        let left = match align {
            Align::Left => x,
            Align::Center => x - w as i32 / 2,
            Align::Right => x - w as i32,
        };
        let s = scale as i32;
        for (n, ch) in text.chars().enumerate() {
            let gx = left + (n as u32 * font::ADVANCE) as i32 * s;
            for (row, bits) in font::glyph(ch).iter().enumerate() {
                for col in 0..font::WIDTH {
                    if bits >> (font::WIDTH - 1 - col) & 1 == 1 {
                        let (px, py) = (gx + col as i32 * s, y + row as i32 * s);
                        self.fill_rect(Rect::new(px, py, s, s), c);
                    }
                }
            }
        }
        w
    }

    /// Text rotated a quarter turn counter-clockwise (reading upward), centred vertically on
    /// `y`, its glyphs' tops at column `x`.
    pub fn text_upward(&mut self, x: i32, y: i32, text: &str, c: Rgb, scale: u32) {
        let w = font::text_width(text, scale) as i32;
        let s = scale as i32;
        let bottom = y + w / 2;
        for (n, ch) in text.chars().enumerate() {
            let along = (n as u32 * font::ADVANCE) as i32 * s;
            for (row, bits) in font::glyph(ch).iter().enumerate() {
                for col in 0..font::WIDTH {
                    if bits >> (font::WIDTH - 1 - col) & 1 == 1 {
                        let px = x + row as i32 * s;
                        let py = bottom - along - (col as i32 + 1) * s;
                        self.fill_rect(Rect::new(px, py, s, s), c);
                    }
                }
            }
        }
    }

    /// The image as PNG bytes (8-bit RGB).
    pub fn encode_png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        {
            let mut enc = png::Encoder::new(&mut out, self.width, self.height);
            enc.set_color(png::ColorType::Rgb);
            enc.set_depth(png::BitDepth::Eight);
            let mut w = enc.write_header().expect("writing to memory cannot fail");
            let data: Vec<u8> = self.pixels.iter().flatten().copied().collect();
            w.write_image_data(&data)
                .expect("the data matches the header");
        }
        out
    }

    /// Writes the image as a PNG file, creating its directory.
    pub fn write_png(&self, path: impl AsRef<Path>) -> io::Result<()> {
        let path = path.as_ref();
        if let Some(dir) = path.parent() {
            if !dir.as_os_str().is_empty() {
                std::fs::create_dir_all(dir)?;
            }
        }
        std::fs::write(path, self.encode_png())
    }

    /// Copies `other` into this image with its top left at (x, y).
    pub fn paste(&mut self, other: &Image, x: i32, y: i32) {
        for oy in 0..other.height as i32 {
            for ox in 0..other.width as i32 {
                if let Some(c) = other.get(ox, oy) {
                    self.set(x + ox, y + oy, c);
                }
            }
        }
    }
}
