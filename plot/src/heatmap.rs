//! Heat maps: a grid of cells coloured by value on a sequential colour map, row and column labels,
//! optional values written in the cells, and a colour bar with ticks.

use crate::axis::{format_tick, ticks, Scale};
use crate::chart::text_scale;
use crate::{font, palette, Align, Image, Rect};

/// A heat map of `values[row][column]`; NaN cells are grey.
#[derive(Debug, Clone, PartialEq)]
pub struct HeatMap {
    pub title: String,
    pub row_labels: Vec<String>,
    pub column_labels: Vec<String>,
    pub values: Vec<Vec<f64>>,
    /// What the colour bar measures.
    pub value_label: String,
    /// The value range of the colour map; `None` takes the data's.
    pub range: Option<(f64, f64)>,
    /// Write each cell's value in it, when it fits.
    pub annotate: bool,
}

impl HeatMap {
    pub fn render(&self, width: u32, height: u32) -> Image {
        let mut img = Image::new(width, height, palette::WHITE);
        self.draw(&mut img, Rect::new(0, 0, width as i32, height as i32));
        img
    }

    /// The value range the colours span.
    pub fn value_range(&self) -> (f64, f64) {
        if let Some(r) = self.range {
            return r;
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for v in self.values.iter().flatten().filter(|v| v.is_finite()) {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        if !lo.is_finite() {
            (0.0, 1.0)
        } else if lo == hi {
            (lo - 0.5, hi + 0.5)
        } else {
            (lo, hi)
        }
    }

    /// The cell rectangle of (row, column) when drawn into `within`.
    pub fn cell(&self, within: Rect, row: usize, column: usize) -> Rect {
        let (grid, cw, ch) = self.layout(within);
        Rect::new(
            grid.x + column as i32 * cw,
            grid.y + row as i32 * ch,
            cw,
            ch,
        )
    }

    fn layout(&self, within: Rect) -> (Rect, i32, i32) {
        let s = text_scale(&within);
        let th = font::text_height(s) as i32;
        let pad = 6 * s as i32;
        let rows = self.values.len().max(1) as i32;
        let cols = self
            .values
            .iter()
            .map(|r| r.len())
            .max()
            .unwrap_or(1)
            .max(1) as i32;
        let row_w = self
            .row_labels
            .iter()
            .map(|l| font::text_width(l, s))
            .max()
            .unwrap_or(0) as i32;
        let col_h = self
            .column_labels
            .iter()
            .map(|l| font::text_width(l, s))
            .max()
            .unwrap_or(0) as i32;
        let bar = 14 * s as i32 + pad + 8 * th;
        let top = pad + if self.title.is_empty() { 0 } else { th + pad };
        let left = pad + row_w + pad;
        let w = (within.w - left - bar - 2 * pad).max(cols);
        let h = (within.h - top - col_h - 3 * pad).max(rows);
        let (cw, ch) = (w / cols, h / rows);
        (
            Rect::new(within.x + left, within.y + top, cw * cols, ch * rows),
            cw,
            ch,
        )
    }

    pub fn draw(&self, img: &mut Image, within: Rect) {
        let s = text_scale(&within);
        let th = font::text_height(s) as i32;
        let pad = 6 * s as i32;
        let (grid, cw, ch) = self.layout(within);
        let (lo, hi) = self.value_range();
        img.fill_rect(within, palette::WHITE);
        if !self.title.is_empty() {
            img.text(
                grid.x + grid.w / 2,
                within.y + pad,
                &self.title,
                palette::TEXT,
                s,
                Align::Center,
            );
        }
        for (r, row) in self.values.iter().enumerate() {
            for (c, v) in row.iter().enumerate() {
                let cell = Rect::new(grid.x + c as i32 * cw, grid.y + r as i32 * ch, cw, ch);
                let x = (v - lo) / (hi - lo);
                let colour = palette::sequential(x);
                img.fill_rect(cell, colour);
                if self.annotate && v.is_finite() {
                    let text = format_tick(*v);
                    if (font::text_width(&text, s) as i32) < cw - 2 && th < ch - 2 {
                        let light = colour.iter().map(|&k| k as u32).sum::<u32>() > 420;
                        let ink = if light {
                            palette::BLACK
                        } else {
                            palette::WHITE
                        };
                        img.text(
                            cell.x + cw / 2,
                            cell.y + (ch - th) / 2,
                            &text,
                            ink,
                            s,
                            Align::Center,
                        );
                    }
                }
            }
        }
        img.stroke_rect(
            Rect::new(grid.x - 1, grid.y - 1, grid.w + 2, grid.h + 2),
            palette::AXIS,
        );
        for (r, label) in self.row_labels.iter().enumerate() {
            let y = grid.y + r as i32 * ch + (ch - th) / 2;
            img.text(grid.x - pad, y, label, palette::TEXT, s, Align::Right);
        }
        for (c, label) in self.column_labels.iter().enumerate() {
            let x = grid.x + c as i32 * cw + (cw - th) / 2;
            let w = font::text_width(label, s) as i32;
            img.text_upward(x, grid.bottom() + pad + w / 2, label, palette::TEXT, s);
        }
        // Colour bar.
        let bar = Rect::new(grid.right() + 2 * pad, grid.y, 14 * s as i32, grid.h);
        for y in 0..bar.h {
            let x = 1.0 - y as f64 / (bar.h - 1).max(1) as f64;
            img.line(
                bar.x,
                bar.y + y,
                bar.right() - 1,
                bar.y + y,
                palette::sequential(x),
                1,
            );
        }
        img.stroke_rect(bar, palette::AXIS);
        let mut widest = 0;
        for v in ticks(lo, hi, Scale::Linear, 6) {
            let y = bar.bottom() - 1 - ((v - lo) / (hi - lo) * (bar.h - 1) as f64).round() as i32;
            img.line(
                bar.right(),
                y,
                bar.right() + 2 * s as i32,
                y,
                palette::AXIS,
                1,
            );
            let w = img.text(
                bar.right() + 3 * s as i32,
                y - th / 2,
                &format_tick(v),
                palette::TEXT,
                s,
                Align::Left,
            );
            widest = widest.max(w as i32);
        }
        if !self.value_label.is_empty() {
            let x = (bar.right() + 3 * s as i32 + widest + pad).min(within.right() - th - pad);
            img.text_upward(x, bar.y + bar.h / 2, &self.value_label, palette::TEXT, s);
        }
    }
}
