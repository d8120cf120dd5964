//! Line and scatter charts: a title, two axes with ticks, grid and labels, any number of series
//! drawn as lines, markers or both, clipped to the plot area, and a legend box.

use crate::axis::{format_tick, ticks, Axis};
use crate::{font, palette, Align, Image, Rect, Rgb};

/// The shape drawn at each point of a series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Marker {
    Circle,
    Square,
    Triangle,
    Diamond,
    Cross,
    Plus,
}

impl Marker {
    /// Marker `i` of the six, cycling.
    pub fn nth(i: usize) -> Marker {
        [
            Marker::Circle,
            Marker::Square,
            Marker::Triangle,
            Marker::Diamond,
            Marker::Cross,
            Marker::Plus,
        ][i % 6]
    }
}

/// How a series is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    Line,
    Scatter(Marker),
    LineAndMarkers(Marker),
}

/// One named series of (x, y) points, drawn in order; a series with an empty name is left out
/// of the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    pub color: Rgb,
    pub style: Style,
}

/// A chart: title, axes, series and whether to draw the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Chart {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
    pub legend: bool,
}

/// The mapping from data to pixels of one drawn chart.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Frame {
    pub area: Rect,
    pub x: (f64, f64),
    pub y: (f64, f64),
}

/// The text scale for a canvas of this size: 2 from 600 pixels wide, else 1.
pub(crate) fn text_scale(r: &Rect) -> u32 {
    if r.w >= 600 {
        2
    } else {
        1
    }
}

impl Chart {
    /// The chart on a white `width`×`height` image.
    pub fn render(&self, width: u32, height: u32) -> Image {
        let mut img = Image::new(width, height, palette::WHITE);
        self.draw(&mut img, Rect::new(0, 0, width as i32, height as i32));
        img
    }

    /// The pixel position of a data point in the last layout for `within` (for tests and for
    /// annotating a chart after drawing it); `None` when the point cannot be drawn.
    pub fn position(&self, within: Rect, x: f64, y: f64) -> Option<(i32, i32)> {
        let f = self.frame(within);
        self.to_pixel(&f, x, y)
    }

    fn to_pixel(&self, f: &Frame, x: f64, y: f64) -> Option<(i32, i32)> {
        if !self.x.accepts(x) || !self.y.accepts(y) {
            return None;
        }
        let (fx, fy) = (self.x.forward(x), self.y.forward(y));
        let (x0, x1) = (self.x.forward(f.x.0), self.x.forward(f.x.1));
        let (y0, y1) = (self.y.forward(f.y.0), self.y.forward(f.y.1));
        let px = f.area.x as f64 + (fx - x0) / (x1 - x0) * (f.area.w - 1) as f64;
        let py = f.area.bottom() as f64 - 1.0 - (fy - y0) / (y1 - y0) * (f.area.h - 1) as f64;
        (px.is_finite() && py.is_finite()).then(|| (px.round() as i32, py.round() as i32))
    }

    pub(crate) fn frame(&self, within: Rect) -> Frame {
        let s = text_scale(&within);
        let xs = self
            .series
            .iter()
            .flat_map(|r| r.points.iter().map(|p| p.0));
        let ys = self
            .series
            .iter()
            .flat_map(|r| r.points.iter().map(|p| p.1));
        let x = self.x.resolve(xs);
        let y = self.y.resolve(ys);
        let th = font::text_height(s) as i32;
        let pad = 6 * s as i32;
        let y_labels = ticks(y.0, y.1, self.y.scale, 8)
            .iter()
            .map(|v| font::text_width(&format_tick(*v), s))
            .max()
            .unwrap_or(0) as i32;
        let left = pad + th + pad + y_labels + pad;
        let top = pad + if self.title.is_empty() { 0 } else { th + pad };
        let bottom = pad + th + pad + th + pad;
        let area = Rect::new(
            within.x + left,
            within.y + top,
            (within.w - left - 3 * pad).max(10),
            (within.h - top - bottom).max(10),
        );
        Frame { area, x, y }
    }

    /// Draws the chart into `within` of an existing image (for panels side by side).
    pub fn draw(&self, img: &mut Image, within: Rect) {
        let s = text_scale(&within);
        let f = self.frame(within);
        let a = f.area;
        let th = font::text_height(s) as i32;
        let pad = 6 * s as i32;
        img.fill_rect(within, palette::WHITE);
        if !self.title.is_empty() {
            img.text(
                a.x + a.w / 2,
                within.y + pad,
                &self.title,
                palette::TEXT,
                s,
                Align::Center,
            );
        }
        // Grid, ticks and tick labels.
        let x_ticks = ticks(
            f.x.0,
            f.x.1,
            self.x.scale,
            (a.w / (60 * s as i32)).max(2) as usize,
        );
        for v in &x_ticks {
            if let Some((px, _)) = self.to_pixel(&f, *v, self.y_in_range(&f)) {
                img.line(px, a.y, px, a.bottom() - 1, palette::GRID, 1);
                img.line(
                    px,
                    a.bottom(),
                    px,
                    a.bottom() + 2 * s as i32,
                    palette::AXIS,
                    1,
                );
                img.text(
                    px,
                    a.bottom() + pad,
                    &format_tick(*v),
                    palette::TEXT,
                    s,
                    Align::Center,
                );
            }
        }
        let y_ticks = ticks(
            f.y.0,
            f.y.1,
            self.y.scale,
            (a.h / (40 * s as i32)).max(2) as usize,
        );
        for v in &y_ticks {
            if let Some((_, py)) = self.to_pixel(&f, self.x_in_range(&f), *v) {
                img.line(a.x, py, a.right() - 1, py, palette::GRID, 1);
                img.line(a.x - 2 * s as i32, py, a.x - 1, py, palette::AXIS, 1);
                img.text(
                    a.x - pad,
                    py - th / 2,
                    &format_tick(*v),
                    palette::TEXT,
                    s,
                    Align::Right,
                );
            }
        }
        img.stroke_rect(Rect::new(a.x - 1, a.y - 1, a.w + 2, a.h + 2), palette::AXIS);
        // Axis labels.
        img.text(
            a.x + a.w / 2,
            a.bottom() + pad + th + pad,
            &self.x.label,
            palette::TEXT,
            s,
            Align::Center,
        );
        img.text_upward(
            within.x + pad,
            a.y + a.h / 2,
            &self.y.label,
            palette::TEXT,
            s,
        );
        // Series: lines first, then markers on top.
        let mut clipped = Image::new(a.w as u32, a.h as u32, palette::WHITE);
        clipped.paste_from(img, a);
        let local = |p: (i32, i32)| (p.0 - a.x, p.1 - a.y);
        for series in &self.series {
            if matches!(series.style, Style::Line | Style::LineAndMarkers(_)) {
                let pts: Vec<(i32, i32)> = series
                    .points
                    .iter()
                    .filter_map(|p| self.to_pixel(&f, p.0, p.1))
                    .map(local)
                    .collect();
                for w in pts.windows(2) {
                    clipped.line(w[0].0, w[0].1, w[1].0, w[1].1, series.color, s as i32);
                }
            }
        }
        for series in &self.series {
            if let Style::Scatter(m) | Style::LineAndMarkers(m) = series.style {
                for p in &series.points {
                    if let Some(q) = self.to_pixel(&f, p.0, p.1) {
                        let (x, y) = local(q);
                        marker(&mut clipped, x, y, m, series.color, 4 * s as i32);
                    }
                }
            }
        }
        img.paste(&clipped, a.x, a.y);
        if self.legend && self.series.iter().any(|r| !r.name.is_empty()) {
            self.draw_legend(img, a, s);
        }
    }

    fn x_in_range(&self, f: &Frame) -> f64 {
        f.x.0
    }
    fn y_in_range(&self, f: &Frame) -> f64 {
        f.y.0
    }

    fn draw_legend(&self, img: &mut Image, a: Rect, s: u32) {
        let th = font::text_height(s) as i32;
        let pad = 4 * s as i32;
        let sample = 16 * s as i32;
        let row = th + pad;
        let named: Vec<&Series> = self.series.iter().filter(|r| !r.name.is_empty()).collect();
        let names = named
            .iter()
            .map(|r| font::text_width(&r.name, s))
            .max()
            .unwrap_or(0) as i32;
        let w = pad + sample + pad + names + pad;
        let h = pad + row * named.len() as i32;
        let r = Rect::new(a.right() - w - pad, a.y + pad, w, h);
        img.fill_rect(r, palette::WHITE);
        img.stroke_rect(r, palette::AXIS);
        for (i, series) in named.iter().enumerate() {
            let cy = r.y + pad + row * i as i32 + th / 2;
            let (x0, x1) = (r.x + pad, r.x + pad + sample);
            if matches!(series.style, Style::Line | Style::LineAndMarkers(_)) {
                img.line(x0, cy, x1, cy, series.color, s as i32);
            }
            if let Style::Scatter(m) | Style::LineAndMarkers(m) = series.style {
                marker(img, (x0 + x1) / 2, cy, m, series.color, 4 * s as i32);
            }
            img.text(
                x1 + pad,
                cy - th / 2,
                &series.name,
                palette::TEXT,
                s,
                Align::Left,
            );
        }
    }
}

impl Image {
    /// Copies the pixels of `r` from `src` into this image's top left.
    fn paste_from(&mut self, src: &Image, r: Rect) {
        for y in 0..r.h {
            for x in 0..r.w {
                if let Some(c) = src.get(r.x + x, r.y + y) {
                    self.set(x, y, c);
                }
            }
        }
    }
}

fn darker(c: Rgb) -> Rgb {
    c.map(|v| (v as u32 * 3 / 5) as u8)
}

/// A marker of radius `r` centred at (x, y), filled with `c` and outlined darker.
pub(crate) fn marker(img: &mut Image, x: i32, y: i32, m: Marker, c: Rgb, r: i32) {
    let edge = darker(c);
    let inside = |dx: i32, dy: i32| -> Option<bool> {
        // Some(true): fill, Some(false): outline, None: outside.
        let (fx, fy) = (dx as f64, dy as f64);
        let rf = r as f64;
        let (d_in, d_out) = match m {
            Marker::Circle => {
                let d = (fx * fx + fy * fy).sqrt();
                (d <= rf - 1.5, d <= rf)
            }
            Marker::Square => {
                let d = fx.abs().max(fy.abs());
                (d <= rf - 2.0, d <= rf - 0.5)
            }
            Marker::Diamond => {
                let d = fx.abs() + fy.abs();
                (d <= rf - 1.5, d <= rf + 0.5)
            }
            Marker::Triangle => {
                // Apex up; base at y = r·0.7.
                let base = rf * 0.7;
                let half = |yy: f64| (yy + rf) / (base + rf) * rf;
                let within = |grow: f64| {
                    fy >= -rf - grow && fy <= base + grow && fx.abs() <= half(fy) + grow
                };
                (within(-1.5), within(0.0))
            }
            Marker::Cross => {
                let on = (fx.abs() - fy.abs()).abs() <= 1.0 && fx.abs() <= rf;
                (on, on)
            }
            Marker::Plus => {
                let on = (fx.abs() <= 1.0 && fy.abs() <= rf) || (fy.abs() <= 1.0 && fx.abs() <= rf);
                (on, on)
            }
        };
        match (d_in, d_out) {
            (true, _) => Some(true),
            (false, true) => Some(false),
            _ => None,
        }
    };
    let hollow_free = matches!(m, Marker::Cross | Marker::Plus);
    for dy in -r - 1..=r + 1 {
        for dx in -r - 1..=r + 1 {
            match inside(dx, dy) {
                Some(true) => img.set(x + dx, y + dy, c),
                Some(false) => img.set(x + dx, y + dy, if hollow_free { c } else { edge }),
                None => {}
            }
        }
    }
}
