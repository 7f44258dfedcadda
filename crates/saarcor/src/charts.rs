//! The report page's charts, drawn with plotters into SVG: hit rate against cache size,
//! unit usage beside the paper's, and frame rate against threads. Legends sit where the
//! lines are not (below the plot, in a row), value labels above their bars, so no label
//! runs into another (the page test in tests/browser checks that in Chromium).

use plotters::prelude::*;

const COLORS: [RGBColor; 5] =
    [RGBColor(31, 119, 180), RGBColor(214, 39, 40), RGBColor(44, 160, 44), RGBColor(148, 103, 189), RGBColor(90, 90, 90)];

/// A chart's SVG, or a sentence saying why it could not be drawn.
fn svg(size: (u32, u32), draw: impl FnOnce(&DrawingArea<SVGBackend<'_>, plotters::coord::Shift>) -> Result<(), String>) -> String {
    let mut s = String::new();
    let r = {
        let root = SVGBackend::with_string(&mut s, size).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string()).and_then(|()| draw(&root)).and_then(|()| root.present().map_err(|e| e.to_string()))
    };
    match r {
        Ok(()) => s,
        Err(e) => format!("<p>(chart not drawn: {e})</p>"),
    }
}

/// A legend as one row of swatches and names under the plot.
fn legend(area: &DrawingArea<SVGBackend<'_>, plotters::coord::Shift>, names: &[(&str, RGBColor)]) -> Result<(), String> {
    let mut x = 60;
    for &(name, c) in names {
        area.draw(&Rectangle::new([(x, 8), (x + 14, 18)], c.filled())).map_err(|e| e.to_string())?;
        area.draw(&Text::new(name.to_string(), (x + 18, 8), ("sans-serif", 13).into_font())).map_err(|e| e.to_string())?;
        x += 30 + 8 * name.chars().count() as i32;
    }
    Ok(())
}

/// Hit rate (percent) against cache size (KB, log scale), one line per cache.
#[must_use]
pub fn hit_rate_chart(series: &[(&str, Vec<(f64, f64)>)]) -> String {
    log2_lines(series, ("cache size, KB", "hit rate %"), 100.0, None)
}

/// Lines with their points over a log2 x axis (labelled by powers of two) and a linear y
/// axis from 0 to `y_top`, one colour a series; with `linear`, the line y = x first,
/// named so in the legend after the series.
fn log2_lines(series: &[(&str, Vec<(f64, f64)>)], desc: (&str, &str), y_top: f64, linear: Option<&str>) -> String {
    svg((620, 340), |root| {
        let (plot, key) = root.split_vertically(300);
        let max_x = series.iter().flat_map(|s| s.1.iter().map(|p| p.0)).fold(2.0f64, f64::max);
        let mut chart = ChartBuilder::on(&plot)
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0f64..max_x.log2(), 0.0f64..y_top)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .light_line_style(TRANSPARENT)
            .x_desc(desc.0)
            .y_desc(desc.1)
            .x_labels(max_x.log2() as usize + 1)
            .x_label_formatter(&|v| format!("{:.0}", v.exp2()))
            .y_label_formatter(&|v| format!("{v:.0}"))
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| e.to_string())?;
        let grey = COLORS[4];
        if linear.is_some() {
            let line: Vec<(f64, f64)> =
                (0..=(max_x.log2() * 8.0) as u32).map(|k| f64::from(k) / 8.0).map(|x| (x, x.exp2())).filter(|p| p.1 <= y_top).collect();
            chart.draw_series(LineSeries::new(line, grey.stroke_width(1))).map_err(|e| e.to_string())?;
        }
        for (i, (_, pts)) in series.iter().enumerate() {
            let pts: Vec<(f64, f64)> = pts.iter().map(|&(x, y)| (x.log2(), y)).collect();
            let c = COLORS[i % 4];
            chart.draw_series(LineSeries::new(pts.iter().copied(), c.stroke_width(2))).map_err(|e| e.to_string())?;
            chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, c.filled()))).map_err(|e| e.to_string())?;
        }
        let mut names: Vec<(&str, RGBColor)> = series.iter().enumerate().map(|(i, s)| (s.0, COLORS[i % 4])).collect();
        if let Some(name) = linear {
            names.push((name, grey));
        }
        legend(&key, &names)
    })
}

/// Unit usage (percent) in groups of four bars (traversal, list, transformation,
/// intersection), one group per row, its value above each bar.
#[must_use]
pub fn usage_chart(rows: &[(String, [f64; 4])]) -> String {
    let names = ["traversal", "list", "transformation", "intersection"];
    let width = (120 + rows.len() as u32 * 150).max(620);
    svg((width, 330), |root| {
        let (plot, key) = root.split_vertically(290);
        let n = rows.len().max(1) as f64;
        let mut chart = ChartBuilder::on(&plot)
            .margin(12)
            .x_label_area_size(30)
            .y_label_area_size(50)
            .build_cartesian_2d(0.0f64..n * 5.0, -14.0f64..115.0)
            .map_err(|e| e.to_string())?;
        chart
            .configure_mesh()
            .disable_x_mesh()
            .light_line_style(TRANSPARENT)
            .x_labels(0)
            .y_label_formatter(&|v| if *v < 0.0 { String::new() } else { format!("{v:.0}") })
            .y_desc("usage %")
            .label_style(("sans-serif", 12))
            .draw()
            .map_err(|e| e.to_string())?;
        // The groups' names under their bars, inside the plot (below its zero line).
        for (g, (label, _)) in rows.iter().enumerate() {
            chart
                .draw_series(std::iter::once(Text::new(label.clone(), (g as f64 * 5.0 + 0.5, -3.0), ("sans-serif", 12).into_font())))
                .map_err(|e| e.to_string())?;
        }
        for (g, (_, u)) in rows.iter().enumerate() {
            for (k, &v) in u.iter().enumerate() {
                let x0 = g as f64 * 5.0 + 0.5 + k as f64;
                let v = v.clamp(0.0, 100.0);
                chart
                    .draw_series(std::iter::once(Rectangle::new([(x0, 0.0), (x0 + 0.9, v)], COLORS[k].filled())))
                    .map_err(|e| e.to_string())?;
                chart
                    .draw_series(std::iter::once(Text::new(format!("{v:.0}"), (x0 + 0.1, v + 7.0), ("sans-serif", 11).into_font())))
                    .map_err(|e| e.to_string())?;
            }
        }
        let names: Vec<(&str, RGBColor)> = names.iter().enumerate().map(|(i, s)| (*s, COLORS[i])).collect();
        legend(&key, &names)
    })
}

/// Frames per second relative to one thread against threads (log scale), one line per
/// index, with the linear line (one thread's rate times the threads) for comparison.
#[must_use]
pub fn threads_chart(series: &[(&str, Vec<(f64, f64)>)]) -> String {
    let max_t = series.iter().flat_map(|s| s.1.iter().map(|p| p.0)).fold(2.0f64, f64::max);
    let max_y = series.iter().flat_map(|s| s.1.iter().map(|p| p.1)).fold(1.0f64, f64::max);
    log2_lines(series, ("threads per pipeline", "fps / fps of one thread"), (max_y * 1.1).min(max_t), Some("linear in threads"))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The charts are SVG with their labels as text.
    #[test]
    fn charts_are_svg_with_labels() {
        let s = hit_rate_chart(&[("traversal", vec![(1.0, 50.0), (64.0, 99.0)]), ("list", vec![(1.0, 20.0), (64.0, 90.0)])]);
        assert!(s.starts_with("<svg") && s.contains("traversal") && s.contains("cache size, KB"), "{s}");
        let u = usage_chart(&[("kd 1024x768".into(), [89.0, 25.0, 51.0, 28.0])]);
        assert!(u.contains("\nkd 1024x768\n") && u.contains("\n89\n") && u.contains("intersection"), "{u}");
        let t = threads_chart(&[("kd", vec![(1.0, 1.0), (32.0, 25.0), (64.0, 27.0)])]);
        assert!(t.contains("linear in threads") && t.contains("threads per pipeline"), "{t}");
    }
}
