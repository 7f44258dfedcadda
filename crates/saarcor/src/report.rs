//! The report's tables: terminal text (Markdown tables read well in a terminal), one JSON
//! line per table row with keys named after the papers' columns, and an HTML page with
//! plots (hit rate against cache size, unit usage bars, per-pixel heat maps, precision
//! images and their differences).

use crate::dynrtp::{FrameModel, ASSUMPTIONS, FP_UNITS, SWEEP_KB};
use crate::precision::PrecisionRow;
use std::fmt::Write as _;

/// SaarCOR's Table 3 frame rate at 512×384 for a scene lucent has (Conference: 22.1 fps,
/// as issue 4 quotes the paper).
#[must_use]
pub fn saarcor_table3_fps(scene: &str) -> Option<f64> {
    scene.to_lowercase().contains("conference").then_some(22.1)
}

/// What SaarCOR's paper says of a scene lucent has. Of its Tables 3 and 4 only the
/// Conference frame rate is on this machine (quoted in issue 4); the rest is the claim of
/// its abstract and first figure.
#[must_use]
pub fn saarcor_paper_says(scene: &str) -> Option<&'static str> {
    let s = scene.to_lowercase();
    if s.contains("conference") {
        Some("Table 3: Conference at 22.1 fps (512x384); the abstract: 20-60 fps at 90 MHz for UT2003, Quake3, Conference and Terrain. Table 4's Conference row is not on this machine")
    } else if s.contains("sunflower") || s.contains("suncor") {
        Some("SunCOR (sunflowers) is one of the paper's dynamic scenes; its Table 3/4 rows are not on this machine")
    } else {
        None
    }
}

/// A report's tables in the two forms `lucent report` prints.
pub trait Tables {
    /// The tables in Markdown.
    fn markdown(&self) -> String;
    /// One JSON line per table row.
    fn json_lines(&self) -> Vec<String>;
}

/// A SaarCOR report of one scene.
#[derive(Clone, Debug, Default)]
pub struct SaarcorReport {
    /// Scene name.
    pub scene: String,
    /// Triangles and instances.
    pub triangles: usize,
    /// Instances.
    pub instances: usize,
    /// Bytes of each index: (name, bytes).
    pub index_bytes: Vec<(&'static str, usize)>,
    /// Table 4 rows (one per index), at the Table 4 size.
    pub table4: Vec<FrameModel>,
    /// Table 3 rows (one per index), at 512×384.
    pub table3: Vec<FrameModel>,
    /// Precision rows.
    pub precision: Vec<PrecisionRow>,
    /// Size of the precision images.
    pub precision_size: (u32, u32),
    /// lucent's own time for the same primary rays (ms, the fast kernels, this machine).
    pub lucent_ms: Option<f64>,
}

fn f1(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.1}")
    } else {
        "inf".into()
    }
}

impl Tables for SaarcorReport {
    fn markdown(&self) -> String {
        let mut s = String::new();
        let _ = writeln!(s, "## SaarCOR DynRTP model: {} ({} triangles, {} instances)\n", self.scene, self.triangles, self.instances);
        if let Some(p) = saarcor_paper_says(&self.scene) {
            let _ = writeln!(s, "The paper: {p}.\n");
        }
        let _ = writeln!(
            s,
            "Index sizes: {}\n",
            self.index_bytes.iter().map(|(n, b)| format!("{n} {:.2} MB", *b as f64 / 1e6)).collect::<Vec<_>>().join(", ")
        );
        let paper = saarcor_table3_fps(&self.scene);
        let _ = writeln!(
            s,
            "### Table 3: frames per second\n\n| index | size | fps | the paper's fps | cycles | hit rays |\n|---|---|---|---|---|---|"
        );
        for r in &self.table3 {
            let p = paper.filter(|_| r.size == (512, 384)).map_or("-".to_string(), |p| format!("{p}"));
            let _ = writeln!(s, "| {} | {}x{} | {:.2} | {p} | {} | {} |", r.index, r.size.0, r.size.1, r.fps, r.cycles, r.hit_rays);
        }
        let _ = writeln!(
            s,
            "\n### Table 4: units, caches, bandwidth\n\n| index | size | fps | usage trav % | usage list % | usage transf % | usage int % | hit trav % | hit list % | hit transf % | MB/s core | MB/s shading | MB/s total |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for r in &self.table4 {
            let _ = writeln!(
                s,
                "| {} | {}x{} | {:.2} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                r.index,
                r.size.0,
                r.size.1,
                r.fps,
                f1(r.usage[0]),
                f1(r.usage[1]),
                f1(r.usage[2]),
                f1(r.usage[3]),
                f1(r.hit[0]),
                f1(r.hit[1]),
                f1(r.hit[2]),
                f1(r.mb_s[0]),
                f1(r.mb_s[1]),
                f1(r.mb_s[2])
            );
        }
        let _ = writeln!(
            s,
            "\nBusy cycles (trav, list, transf, int, memory): {}",
            self.table4.iter().map(|r| format!("{} {:?}", r.index, r.busy)).collect::<Vec<_>>().join("; ")
        );
        if let Some(ms) = self.lucent_ms {
            let _ = writeln!(s, "\nlucent on this machine, the same primary rays: {ms:.1} ms ({:.1} fps).", 1e3 / ms.max(1e-9));
        }
        let _ = writeln!(s, "\n### Table 2's question: floating-point operations per unit operation\n\n| unit | add | mul | div | cmp | one operation |\n|---|---|---|---|---|---|");
        for (u, a, m, d, c, what) in FP_UNITS {
            let _ = writeln!(s, "| {u} | {a} | {m} | {d} | {c} | {what} |");
        }
        if !self.precision.is_empty() {
            let _ = writeln!(
                s,
                "\n### Precision ({}x{}, kd index, eye-light shading)\n\n| format | changed hits % | PSNR dB |\n|---|---|---|",
                self.precision_size.0, self.precision_size.1
            );
            for p in &self.precision {
                let _ = writeln!(s, "| {} | {:.3} | {} |", p.format.name(), p.changed_pct, f1(p.psnr));
            }
        }
        let _ = writeln!(s, "\n### Modelling assumptions\n");
        for a in ASSUMPTIONS {
            let _ = writeln!(s, "- {a}");
        }
        s
    }

    fn json_lines(&self) -> Vec<String> {
        let mut out = Vec::new();
        for (table, rows) in [("saarcor_table3", &self.table3), ("saarcor_table4", &self.table4)] {
            for r in rows {
                let paper = saarcor_table3_fps(&self.scene).filter(|_| table == "saarcor_table3" && r.size == (512, 384));
                out.push(format!(
                    "{{\"table\":\"{table}\",\"paper_fps\":{},\"scene\":{},\"index\":\"{}\",\"width\":{},\"height\":{},\"fps\":{},\"cycles\":{},\"usage_trav\":{},\"usage_list\":{},\"usage_transf\":{},\"usage_int\":{},\"hit_trav\":{},\"hit_list\":{},\"hit_transf\":{},\"mb_s_core\":{},\"mb_s_shading\":{},\"mb_s_total\":{}}}",
                    paper.map_or("null".into(), num),
                    json_str(&self.scene),
                    r.index,
                    r.size.0,
                    r.size.1,
                    num(r.fps),
                    r.cycles,
                    num(r.usage[0]),
                    num(r.usage[1]),
                    num(r.usage[2]),
                    num(r.usage[3]),
                    num(r.hit[0]),
                    num(r.hit[1]),
                    num(r.hit[2]),
                    num(r.mb_s[0]),
                    num(r.mb_s[1]),
                    num(r.mb_s[2])
                ));
            }
        }
        for p in &self.precision {
            out.push(format!(
                "{{\"table\":\"precision\",\"scene\":{},\"format\":\"{}\",\"changed_pct\":{},\"psnr_db\":{}}}",
                json_str(&self.scene),
                p.format.name(),
                num(p.changed_pct),
                num(p.psnr)
            ));
        }
        out
    }
}

impl SaarcorReport {
    /// The HTML page; images it refers to are written into `dir` under `stem`.
    ///
    /// # Errors
    /// When an image cannot be written.
    pub fn html(&self, dir: &std::path::Path, stem: &str) -> Result<String, lucent_render::OutputError> {
        let mut h = page_head(&format!("lucent report: {}", self.scene));
        h += &md_to_html_tables(&self.markdown());
        if let Some(r) = self.table4.first() {
            let mut series = Vec::new();
            for (i, name) in ["traversal", "list", "transformation"].iter().enumerate() {
                series.push((*name, r.sweep.iter().map(|&(kb, v)| (kb as f64, v[i])).collect::<Vec<_>>()));
            }
            h += "<h3>Hit rate against cache size (direct mapped)</h3>";
            h += &line_chart(&series, "cache size, KB (log)", "hit rate %");
        }
        h += "<h3>Unit usage</h3>";
        let bars: Vec<(String, [f64; 4])> =
            self.table4.iter().map(|r| (format!("{} {}x{}", r.index, r.size.0, r.size.1), r.usage)).collect();
        h += &usage_bars(&bars);
        for r in &self.table4 {
            let (w, hh) = r.size;
            let steps = format!("{stem}-{}-steps.png", r.index);
            let misses = format!("{stem}-{}-misses.png", r.index);
            heat(&r.heat_steps, w, hh).save(&dir.join(&steps))?;
            heat(&r.heat_misses, w, hh).save(&dir.join(&misses))?;
            let _ = write!(
                h,
                "<h3>{} index: traversal steps and cache misses per packet</h3><p><img src=\"{steps}\" width=\"{}\"> <img src=\"{misses}\" width=\"{}\"></p><p>Black to white: 0 to the frame's maximum ({} steps, {} misses).</p>",
                r.index,
                w.min(512),
                w.min(512),
                r.heat_steps.iter().copied().fold(0.0, f32::max),
                r.heat_misses.iter().copied().fold(0.0, f32::max)
            );
        }
        if let Some(reference) = self.precision.first() {
            let (w, hh) = self.precision_size;
            h += "<h3>Precision: eye-light images and |difference| x 8 against f32</h3><table><tr>";
            for p in &self.precision {
                let img = format!("{stem}-precision-{}.png", p.format.name());
                grey(&p.image, w, hh, 1.0).save(&dir.join(&img))?;
                let diff: Vec<f32> = p.image.iter().zip(&reference.image).map(|(a, b)| (a - b).abs()).collect();
                let dimg = format!("{stem}-precision-{}-diff.png", p.format.name());
                grey(&diff, w, hh, 8.0).save(&dir.join(&dimg))?;
                let _ = write!(
                    h,
                    "<td><b>{}</b> ({:.3}% hits changed, PSNR {} dB)<br><img src=\"{img}\" width=\"256\"><br><img src=\"{dimg}\" width=\"256\"></td>",
                    p.format.name(),
                    p.changed_pct,
                    f1(p.psnr)
                );
            }
            h += "</tr></table>";
        }
        h += "</body></html>\n";
        Ok(h)
    }
}

/// A REND3R report of one program.
#[derive(Clone, Debug, Default)]
pub struct Rend3rReport {
    /// Program path.
    pub program: String,
    /// Mode name.
    pub mode: &'static str,
    /// Per frame: (frame, shapes, lights, worst cycles, board cycles, hit pixels, lucent ms).
    pub frames: Vec<(u64, u64, u64, u64, u64, u64, f64)>,
    /// Frame size.
    pub size: (u32, u32),
}

/// REND3R's Table IV as the formula gives it at 512×384: (spheres, lights, seconds), for
/// the sphere counts and light counts of the table's scenes.
#[must_use]
pub fn table_iv() -> Vec<(u64, u64, f64, Option<f64>)> {
    use rend3r_machine::cycles::{ray_traced, PAPER_ROWS};
    let px = 512 * 384;
    let mut rows = Vec::new();
    for lights in [0, 1] {
        for n in [1, 16, 256, 4096] {
            let s = ray_traced(n, lights, px, px).seconds().0;
            let paper = PAPER_ROWS.iter().find(|r| r.0 == n && r.1 == lights).map(|r| r.2);
            rows.push((n, lights, s, paper));
        }
    }
    rows
}

impl Tables for Rend3rReport {
    fn markdown(&self) -> String {
        use rend3r_machine::cycles::PAPER_MEASURED;
        let mut s = String::new();
        let _ = writeln!(s, "## REND3R cycle model: {} ({}, {}x{})\n", self.program, self.mode, self.size.0, self.size.1);
        let _ = writeln!(
            s,
            "| frame | shapes | lights | cycles worst | cycles board | pixels hit | seconds worst | seconds board | lucent ms | x faster than the board |\n|---|---|---|---|---|---|---|---|---|---|"
        );
        for &(f, sh, l, w, b, hits, ms) in &self.frames {
            let _ = writeln!(
                s,
                "| {f} | {sh} | {l} | {w} | {b} | {hits} | {:.4} | {:.4} | {ms:.2} | {:.0} |",
                w as f64 / 1e8,
                b as f64 / 1e8,
                b as f64 / 1e8 * 1e3 / ms.max(1e-9)
            );
        }
        let _ = writeln!(s, "\n### Table IV (512x384, 100 MHz): the formula (shapes + 205) x (lights + 1) cycles a pixel\n\n| spheres | lights | seconds (formula) | the paper |\n|---|---|---|---|");
        for (n, l, sec, paper) in table_iv() {
            let _ = writeln!(s, "| {n} | {l} | {sec:.3} | {} |", paper.map_or("not on this machine".to_string(), |p| format!("{p:.3} s")));
        }
        let (sh, l, measured, formula) = PAPER_MEASURED;
        let _ = writeln!(
            s,
            "\nThe paper's measured frame of {sh} shapes and {l} light: {measured} cycles on the board against the formula's {formula} ({:.1}% of it); the board model here spends light rays only where the camera ray hit.",
            100.0 * measured as f64 / formula as f64
        );
        s
    }

    fn json_lines(&self) -> Vec<String> {
        let mut out: Vec<String> = self
            .frames
            .iter()
            .map(|&(f, sh, l, w, b, hits, ms)| {
                format!(
                    "{{\"table\":\"rend3r_frames\",\"program\":{},\"frame\":{f},\"shapes\":{sh},\"lights\":{l},\"pixels_hit\":{hits},\"cycles_worst\":{w},\"cycles_board\":{b},\"seconds\":{},\"lucent_ms\":{}}}",
                    json_str(&self.program),
                    num(b as f64 / 1e8),
                    num(ms)
                )
            })
            .collect();
        for (n, l, sec, paper) in table_iv() {
            out.push(format!(
                "{{\"table\":\"rend3r_table_iv\",\"shapes\":{n},\"lights\":{l},\"cycles_worst\":{},\"seconds\":{},\"paper_seconds\":{}}}",
                (sec * 1e8).round(),
                num(sec),
                paper.map_or("null".into(), num)
            ));
        }
        out
    }
}

impl Rend3rReport {
    /// The HTML page.
    #[must_use]
    pub fn html(&self) -> String {
        let mut h = page_head(&format!("lucent report: {}", self.program));
        h += &md_to_html_tables(&self.markdown());
        h += "</body></html>\n";
        h
    }
}

fn num(x: f64) -> String {
    if x.is_finite() {
        format!("{x:.4}")
    } else {
        "null".into()
    }
}

fn json_str(s: &str) -> String {
    let mut o = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => o += "\\\"",
            '\\' => o += "\\\\",
            c if (c as u32) < 0x20 => {
                let _ = write!(o, "\\u{:04x}", c as u32);
            }
            c => o.push(c),
        }
    }
    o + "\""
}

fn esc(s: &str) -> String {
    s.replace('&', "&amp;").replace('<', "&lt;").replace('>', "&gt;")
}

fn page_head(title: &str) -> String {
    format!(
        "<!doctype html><html><head><meta charset=\"utf-8\"><title>{}</title><style>body{{font-family:sans-serif;max-width:1100px;margin:2em auto}}table{{border-collapse:collapse}}td,th{{border:1px solid #ccc;padding:2px 6px;text-align:right}}</style></head><body>",
        esc(title)
    )
}

/// The report's Markdown as HTML: headings, tables, list items and paragraphs.
fn md_to_html_tables(md: &str) -> String {
    let mut h = String::new();
    let mut in_table = false;
    for line in md.lines() {
        if let Some(row) = line.strip_prefix('|') {
            if row.starts_with("---") {
                continue;
            }
            if !in_table {
                h += "<table>";
                in_table = true;
            }
            h += "<tr>";
            for cell in row.trim_end_matches('|').split('|') {
                let _ = write!(h, "<td>{}</td>", esc(cell.trim()));
            }
            h += "</tr>";
            continue;
        }
        if in_table {
            h += "</table>";
            in_table = false;
        }
        if let Some(t) = line.strip_prefix("### ") {
            let _ = write!(h, "<h3>{}</h3>", esc(t));
        } else if let Some(t) = line.strip_prefix("## ") {
            let _ = write!(h, "<h2>{}</h2>", esc(t));
        } else if let Some(t) = line.strip_prefix("- ") {
            let _ = write!(h, "<li>{}</li>", esc(t));
        } else if !line.trim().is_empty() {
            let _ = write!(h, "<p>{}</p>", esc(line));
        }
    }
    if in_table {
        h += "</table>";
    }
    h
}

const COLORS: [&str; 4] = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd"];

/// An SVG line chart over a log2 x axis (cache sizes) and a 0..100 y axis.
fn line_chart(series: &[(&str, Vec<(f64, f64)>)], xlabel: &str, ylabel: &str) -> String {
    let (w, h, l, b) = (560.0, 300.0, 50.0, 40.0);
    let xs = |kb: f64| l + (kb.log2() / (SWEEP_KB[SWEEP_KB.len() - 1] as f64).log2()) * (w - l - 20.0);
    let ys = |v: f64| (h - b) - v / 100.0 * (h - b - 10.0);
    let mut s = format!("<svg width=\"{w}\" height=\"{h}\" xmlns=\"http://www.w3.org/2000/svg\" font-size=\"11\">");
    let _ = write!(s, "<line x1=\"{l}\" y1=\"{}\" x2=\"{}\" y2=\"{}\" stroke=\"black\"/><line x1=\"{l}\" y1=\"10\" x2=\"{l}\" y2=\"{}\" stroke=\"black\"/>", h - b, w - 20.0, h - b, h - b);
    for kb in SWEEP_KB {
        let _ = write!(s, "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{kb}</text>", xs(kb as f64), h - b + 14.0);
    }
    for v in [0, 25, 50, 75, 100] {
        let _ = write!(s, "<text x=\"{}\" y=\"{}\" text-anchor=\"end\">{v}</text>", l - 4.0, ys(f64::from(v)) + 4.0);
    }
    let _ = write!(s, "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text><text x=\"12\" y=\"{}\" transform=\"rotate(-90 12 {})\" text-anchor=\"middle\">{}</text>", (w + l) / 2.0, h - 6.0, esc(xlabel), h / 2.0, h / 2.0, esc(ylabel));
    for (i, (name, pts)) in series.iter().enumerate() {
        let path: Vec<String> = pts.iter().map(|&(x, y)| format!("{:.1},{:.1}", xs(x), ys(y))).collect();
        let _ = write!(s, "<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"2\" points=\"{}\"/>", COLORS[i % 4], path.join(" "));
        let _ = write!(s, "<text x=\"{}\" y=\"{}\" fill=\"{}\">{}</text>", l + 10.0, 20.0 + 14.0 * i as f64, COLORS[i % 4], esc(name));
    }
    s + "</svg>"
}

/// SVG bars of unit usage per row.
fn usage_bars(rows: &[(String, [f64; 4])]) -> String {
    let names = ["trav", "list", "transf", "int"];
    let (bw, gap) = (18.0, 30.0);
    let w = 60.0 + rows.len() as f64 * (4.0 * bw + gap);
    let h = 240.0;
    let mut s = format!("<svg width=\"{w}\" height=\"{h}\" xmlns=\"http://www.w3.org/2000/svg\" font-size=\"11\">");
    for (r, (label, u)) in rows.iter().enumerate() {
        let x0 = 40.0 + r as f64 * (4.0 * bw + gap);
        for (k, v) in u.iter().enumerate() {
            let bh = v.clamp(0.0, 100.0) / 100.0 * 180.0;
            let _ = write!(
                s,
                "<rect x=\"{}\" y=\"{}\" width=\"{}\" height=\"{bh}\" fill=\"{}\"/><text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{}</text>",
                x0 + k as f64 * bw,
                200.0 - bh,
                bw - 2.0,
                COLORS[k],
                x0 + k as f64 * bw + bw / 2.0,
                214.0,
                names[k]
            );
            let _ = write!(s, "<text x=\"{}\" y=\"{}\" text-anchor=\"middle\">{:.0}</text>", x0 + k as f64 * bw + bw / 2.0, 196.0 - bh, v);
        }
        let _ = write!(s, "<text x=\"{x0}\" y=\"232\">{}</text>", esc(label));
    }
    s + "</svg>"
}

/// A heat map: 0 black to the maximum white, through blue and red.
fn heat(v: &[f32], w: u32, h: u32) -> lucent_render::Film {
    let max = v.iter().copied().fold(0.0f32, f32::max).max(1e-9);
    let mut f = lucent_render::Film::new(w, h);
    for (p, &x) in f.pixels.iter_mut().zip(v) {
        let t = x / max;
        // sRGB output: the film holds linear values.
        *p = glam::Vec3::new(t.powf(0.7), (t * t).powf(1.5), (1.0 - (2.0 * t - 1.0).abs()) * 0.8 + t * t * 0.2).powf(2.2);
    }
    f
}

fn grey(v: &[f32], w: u32, h: u32, gain: f32) -> lucent_render::Film {
    let mut f = lucent_render::Film::new(w, h);
    for (p, &x) in f.pixels.iter_mut().zip(v) {
        *p = glam::Vec3::splat((x * gain).clamp(0.0, 1.0).powf(2.2));
    }
    f
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every row of Table IV has the paper's printed figure beside the formula's, and they
    /// agree to the printed digits.
    #[test]
    fn table_iv_rows() {
        let rows = table_iv();
        assert_eq!(rows.len(), 8);
        for (n, l, s, p) in rows {
            let p = p.unwrap_or_else(|| panic!("{n} spheres {l} lights: no paper figure"));
            assert!((s - p).abs() < 0.0005, "{n} spheres {l} lights: {s} vs {p}");
        }
    }

    #[test]
    fn markdown_tables_become_html() {
        let h = md_to_html_tables("## T\n\n| a | b |\n|---|---|\n| 1 | <2> |\n\n- x");
        assert_eq!(h, "<h2>T</h2><table><tr><td>a</td><td>b</td></tr><tr><td>1</td><td>&lt;2&gt;</td></tr></table><li>x</li>");
        assert_eq!(json_str("a\"b\n"), "\"a\\\"b\\u000a\"");
    }
}
