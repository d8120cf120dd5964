//! The plot crate draws what it is given: the font covers printable ASCII with distinct glyphs,
//! ticks are nice numbers inside the range, a PNG decodes back to the same pixels, points land
//! where the axes put them in their series' colour, and heat-map cells take the colour of their
//! value. Sample charts go to `target/plot-samples/` for looking at.

use plot::{
    font, format_tick, palette, ticks, Axis, Chart, HeatMap, Image, Marker, Rect, Scale, Series,
    Style,
};
use std::collections::HashSet;

#[test]
fn the_font_covers_printable_ascii_with_distinct_well_formed_glyphs() {
    let mut seen = HashSet::new();
    for c in ' '..='~' {
        assert!(font::has_glyph(c), "no glyph for {c:?}");
        assert!(
            seen.insert(font::glyph(c)),
            "{c:?} looks like another glyph"
        );
    }
    for (c, rows) in font::table() {
        let rows: Vec<&str> = rows.split(' ').collect();
        assert_eq!(rows.len(), 7, "{c:?}");
        assert!(
            rows.iter()
                .all(|r| r.len() == 5 && r.bytes().all(|b| b == b'#' || b == b'.')),
            "{c:?}"
        );
    }
    assert_eq!(font::glyph(' '), [0; 7]);
    // Outside ASCII: a box, not nothing.
    assert_eq!(font::glyph('µ')[0], 0b11111);
    assert_eq!(font::text_width("ab", 2), (2 * 6 - 1) * 2);
}

#[test]
fn linear_ticks_are_one_two_five_steps_inside_the_range() {
    assert_eq!(
        ticks(0.0, 1.0, Scale::Linear, 5),
        vec![0.0, 0.2, 0.4, 0.6, 0.8, 1.0]
    );
    assert_eq!(
        ticks(-3.0, 7.0, Scale::Linear, 5),
        vec![-2.0, 0.0, 2.0, 4.0, 6.0]
    );
    let t = ticks(0.013, 0.087, Scale::Linear, 8);
    assert!(t.len() >= 4 && t.len() <= 9, "{t:?}");
    assert!(t.iter().all(|v| (0.013..=0.087).contains(v)));
    assert!(ticks(1.0, 1.0, Scale::Linear, 5).is_empty());
}

#[test]
fn log_ticks_are_decades_and_thin_out() {
    assert_eq!(
        ticks(0.5, 2000.0, Scale::Log10, 10),
        vec![1.0, 10.0, 100.0, 1000.0]
    );
    let wide = ticks(1e-20, 1e20, Scale::Log10, 6);
    assert!(wide.len() <= 7 && wide.len() >= 4, "{wide:?}");
    // Under two decades, 2 and 5 join in.
    assert_eq!(
        ticks(1.5, 60.0, Scale::Log10, 10),
        vec![2.0, 5.0, 10.0, 20.0, 50.0]
    );
    assert!(ticks(-1.0, 10.0, Scale::Log10, 5).is_empty());
}

#[test]
fn tick_labels_are_short() {
    assert_eq!(format_tick(0.0), "0");
    assert_eq!(format_tick(0.25), "0.25");
    assert_eq!(format_tick(1500.0), "1500");
    assert_eq!(format_tick(1e-7), "1e-7");
    assert_eq!(format_tick(2.5e6), "2.5e6");
    assert_eq!(format_tick(-40.0), "-40");
}

fn decode(bytes: &[u8]) -> (u32, u32, Vec<u8>) {
    let dec = png::Decoder::new(std::io::Cursor::new(bytes));
    let mut reader = dec.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size().unwrap()];
    let info = reader.next_frame(&mut buf).unwrap();
    assert_eq!(info.color_type, png::ColorType::Rgb);
    buf.truncate(info.buffer_size());
    (info.width, info.height, buf)
}

#[test]
fn a_png_decodes_to_the_same_pixels() {
    let mut img = Image::new(7, 5, palette::WHITE);
    img.set(3, 2, [10, 20, 30]);
    img.fill_rect(Rect::new(0, 0, 2, 2), [200, 0, 0]);
    let (w, h, data) = decode(&img.encode_png());
    assert_eq!((w, h), (7, 5));
    assert_eq!(&data[(2 * 7 + 3) * 3..(2 * 7 + 3) * 3 + 3], &[10, 20, 30]);
    assert_eq!(&data[0..3], &[200, 0, 0]);
    assert_eq!(&data[(4 * 7 + 6) * 3..], &[255, 255, 255]);
}

fn sample_chart() -> Chart {
    Chart {
        title: "Time per ray against misclassification".into(),
        x: Axis::new("time per ray (us)", Scale::Log10),
        y: Axis::new("misclassified pairs (%)", Scale::Linear),
        series: vec![
            Series {
                name: "f32 filter only".into(),
                points: vec![(0.3, 1.5), (0.5, 2.5), (2.0, 0.4)],
                color: palette::series(0),
                style: Style::Scatter(Marker::Circle),
            },
            Series {
                name: "exact only".into(),
                points: vec![(30.0, 0.0), (80.0, 0.0)],
                color: palette::series(1),
                style: Style::LineAndMarkers(Marker::Square),
            },
        ],
        legend: true,
    }
}

#[test]
fn points_land_where_the_axes_put_them_in_their_colour() {
    let chart = sample_chart();
    let img = chart.render(900, 600);
    let within = Rect::new(0, 0, 900, 600);
    for s in &chart.series {
        for p in &s.points {
            let (x, y) = chart.position(within, p.0, p.1).expect("drawable");
            assert_eq!(img.get(x, y), Some(s.color), "{} at {p:?}", s.name);
        }
    }
    // Larger x is further right; larger y is higher up.
    let a = chart.position(within, 0.3, 1.5).unwrap();
    let b = chart.position(within, 2.0, 0.4).unwrap();
    assert!(b.0 > a.0 && b.1 > a.1);
    // Text and axes drew dark pixels; the corner stays white.
    let dark = (0..600)
        .flat_map(|y| (0..900).map(move |x| (x, y)))
        .filter(|&(x, y)| img.get(x, y) == Some(palette::TEXT))
        .count();
    assert!(dark > 2000, "{dark}");
    assert_eq!(img.get(899, 599), Some(palette::WHITE));
    // A log axis cannot draw 0.
    assert!(chart.position(within, 0.0, 1.0).is_none());
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plot-samples");
    img.write_png(dir.join("chart.png")).unwrap();
    let (w, h, _) = decode(&std::fs::read(dir.join("chart.png")).unwrap());
    assert_eq!((w, h), (900, 600));
}

#[test]
fn heat_map_cells_take_the_colour_of_their_value() {
    let map = HeatMap {
        title: "VARY share by family and mode".into(),
        row_labels: vec!["watertight".into(), "far".into()],
        column_labels: vec!["f32".into(), "f64".into(), "exact".into()],
        values: vec![vec![0.0, 0.5, 1.0], vec![0.25, f64::NAN, 0.75]],
        value_label: "share".into(),
        range: Some((0.0, 1.0)),
        annotate: true,
    };
    let img = map.render(700, 420);
    let within = Rect::new(0, 0, 700, 420);
    for (r, row) in map.values.iter().enumerate() {
        for (c, v) in row.iter().enumerate() {
            let cell = map.cell(within, r, c);
            // A corner pixel of the cell, away from the annotation.
            assert_eq!(
                img.get(cell.x + 1, cell.y + 1),
                Some(palette::sequential(*v)),
                "cell {r},{c}"
            );
        }
    }
    assert_ne!(palette::sequential(0.0), palette::sequential(1.0));
    assert_eq!(palette::sequential(f64::NAN), palette::MISSING);
    let dir = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../target/plot-samples");
    img.write_png(dir.join("heatmap.png")).unwrap();
}
