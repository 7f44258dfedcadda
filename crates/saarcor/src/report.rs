//! The report's tables: terminal text (Markdown tables read well in a terminal), one JSON
//! line per table row with keys named after the papers' columns, and an HTML page with
//! plots (hit rate against cache size, unit usage bars, per-pixel heat maps, precision
//! images and their differences).

use crate::dynrtp::{FrameModel, ASSUMPTIONS, FP_UNITS};
use crate::paper;
use crate::precision::PrecisionRow;
use std::fmt::Write as _;

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
    /// The same frames at each of [`crate::dynrtp::THREAD_SWEEP`]'s thread counts.
    pub threads: Vec<FrameModel>,
    /// The kd index's Table 4 frame under other modelling choices: (the choice, frame).
    pub variants: Vec<(String, FrameModel)>,
    /// Precision rows.
    pub precision: Vec<PrecisionRow>,
    /// Pixel-Planes 5's integer sphere tracer against f64 ([`crate::pp5::study`]).
    pub pp5: Vec<crate::pp5::Pp5Row>,
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
        let pname = paper::paper_name(&self.scene);
        if let Some((n, what)) = pname.and_then(|n| paper::SCENES.iter().find(|r| r.0 == n)) {
            let _ = writeln!(s, "The paper's {n}: lucent has {what}.\n");
        }
        let _ = writeln!(
            s,
            "Index sizes: {}\n",
            self.index_bytes.iter().map(|(n, b)| format!("{n} {:.2} MB", *b as f64 / 1e6)).collect::<Vec<_>>().join(", ")
        );
        let t3 = paper::table3_of(&self.scene);
        let _ = writeln!(
            s,
            "### Table 3: frames per second (512x384)\n\n| index | fps | the paper's SaarCOR fps | model / paper | the paper's OpenRT fps | cycles | hit rays | Mrays/s |\n|---|---|---|---|---|---|---|---|"
        );
        for r in &self.table3 {
            let (p, ratio, o) = t3.filter(|_| r.size == (512, 384)).map_or(("-".into(), "-".into(), "-".into()), |p| {
                (format!("{}", p.saarcor_fps), format!("{:.2}", r.fps / p.saarcor_fps), format!("{}", p.openrt_fps))
            });
            let mrays = r.fps * f64::from(r.size.0) * f64::from(r.size.1) / 1e6;
            let _ = writeln!(s, "| {} | {:.2} | {p} | {ratio} | {o} | {} | {} | {mrays:.1} |", r.index, r.fps, r.cycles, r.hit_rays);
        }
        if let Some(ms) = self.lucent_ms {
            let _ = writeln!(
                s,
                "\nlucent on this machine, the same primary rays at the Table 4 size: {ms:.1} ms ({:.1} fps).",
                1e3 / ms.max(1e-9)
            );
        }
        let t4 = paper::table4_of(&self.scene);
        let _ = writeln!(
            s,
            "\n### Table 4: units, caches, bandwidth\n\n| index | size | fps | usage trav % | usage list % | usage transf % | usage int % | hit trav % | hit list % | hit transf % | MB/s core | MB/s shading | MB/s total |\n|---|---|---|---|---|---|---|---|---|---|---|---|---|"
        );
        for r in &self.table4 {
            let _ = writeln!(s, "| {} | {}x{} | {} |", r.index, r.size.0, r.size.1, table4_cells(&figures(r)).join(" | "));
        }
        if let Some(p) = t4 {
            let _ = writeln!(s, "| the paper | 1024x768 | {} |", table4_cells(&paper_figures(p)).join(" | "));
        }
        let _ = writeln!(
            s,
            "\nBusy cycles (trav, list, transf, int, memory): {}",
            self.table4.iter().map(|r| format!("{} {:?}", r.index, r.busy)).collect::<Vec<_>>().join("; ")
        );
        if let (Some(p), Some(kd)) = (t4, self.table4.iter().find(|r| r.index == "kd" && r.size == (1024, 768))) {
            self.gaps(&mut s, p, kd);
        }
        if !self.threads.is_empty() {
            let _ = writeln!(
                s,
                "\n### Threads per pipeline (512x384)\n\nThe paper: \"Multi-threading increases performance almost linear up to 32 threads per DynRTP. Using 64 threads further improves performance by only about 10%.\"\n\n| index | threads | fps | x 1 thread | usage trav % | usage list % | usage transf % | usage int % | hit trav % | hit list % | hit transf % |\n|---|---|---|---|---|---|---|---|---|---|---|"
            );
            for r in &self.threads {
                let one = self.threads.iter().find(|q| q.index == r.index && q.threads == 1).map_or(f64::NAN, |q| q.fps);
                let cells = table4_cells(&figures(r));
                let _ = writeln!(s, "| {} | {} | {:.2} | {:.2} | {} |", r.index, r.threads, r.fps, r.fps / one, cells[1..8].join(" | "));
            }
            for ix in ["bvh", "kd"] {
                if let Some((x32, x64)) = self.scaling(ix) {
                    let _ = writeln!(
                        s,
                        "\n{ix}: 32 threads {x32:.1}x one thread; 64 threads {:+.0}% over 32 (the paper: almost 32x, about +10%).",
                        100.0 * (x64 - 1.0)
                    );
                }
            }
        }
        let _ = writeln!(s, "\n### Table 1: floating-point units of the four designs, RTDyn1 against each\n\n| ratio | the paper, without traversal % | derived here % | the paper, full design % | derived here % |\n|---|---|---|---|---|");
        for (name, a, b, p0, p1) in paper::table1_derived() {
            let _ = writeln!(s, "| {name} | {p0} | {a:.0} | {p1} | {b:.0} |");
        }
        let _ = writeln!(s, "\nDerived from the units counted as follows (a design's cost: its adders, multipliers, dividers and comparators, all counted alike): RTDyn1 = T + I, RTDyn2 = T + S + Iw, RTDyn3 = T + S + Ip, RTstatic = S + Iw, and K added for the full design.\n\n| unit | add | mul | div | cmp | what |\n|---|---|---|---|---|---|");
        for (n, what, u) in paper::DESIGN_UNITS {
            let _ = writeln!(s, "| {n} | {} | {} | {} | {} | {what} |", u.add, u.mul, u.div, u.cmp);
        }
        let _ = writeln!(
            s,
            "\nThe paper's two columns imply a traversal unit of {:.2}x RTDyn1's other units (solved from the RTstatic row): with RTDyn1's 24 from Table 2, 13 units, where Table 2 lists 21 (4 adders, 4 dividers, 13 comparators): its Table 1 seems to count the traversal unit's comparators alone or weigh them below the arithmetic.",
            paper::table1_implied_traversal()
        );
        let _ = writeln!(s, "\n### Table 2: floating-point units of one pipeline (the paper) and per operation (lucent's kernels)\n\n| unit | add | mul | div | cmp | memory KB |\n|---|---|---|---|---|---|");
        for (u, f, kb) in paper::TABLE2 {
            let _ = writeln!(s, "| {u} | {} | {} | {} | {} | {kb} |", f.add, f.mul, f.div, f.cmp);
        }
        let (tot, kb) = paper::TABLE2_TOTAL;
        let _ = writeln!(s, "| Total | {} | {} | {} | {} | {kb} |", tot.add, tot.mul, tot.div, tot.cmp);
        let _ = writeln!(
            s,
            "\nlucent's kernels, per ray and operation:\n\n| unit | add | mul | div | cmp | one operation |\n|---|---|---|---|---|---|"
        );
        for (u, a, m, d, c, what) in FP_UNITS {
            let _ = writeln!(s, "| {u} | {a} | {m} | {d} | {c} | {what} |");
        }
        self.text_figures(&mut s);
        let _ = writeln!(s, "\n### The paper's scenes\n\n| scene | triangles | objects | lucent |\n|---|---|---|---|");
        for (r, (_, what)) in paper::TABLE3.iter().zip(paper::SCENES) {
            let _ = writeln!(s, "| {} | {} | {} | {what} |", r.scene, r.triangles, r.objects);
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
        if !self.pp5.is_empty() {
            let _ = writeln!(
                s,
                "\n### Pixel-Planes 5's arithmetic (its sphere tracer, ten spheres in 1280x1024 display units)\n\nThe paper: \"the ray parametric parameters, the model description, and most intermediate values are kept as 12 or 24 bit integers\"; the discriminant \"on the order of 2^36\"; \"an additional 6 bits were added to the right of T's binary point\"; 640x512 while the joystick moves, 1280x1024 when it stops. Against the same tracer in f64:\n\n| arithmetic | size | primary hits changed % | reflections changed % | PSNR dB | discriminant bits |\n|---|---|---|---|---|---|"
            );
            for r in &self.pp5 {
                let _ = writeln!(
                    s,
                    "| {} | {}x{} | {:.2} | {:.2} | {} | {} |",
                    r.arith,
                    r.size.0,
                    r.size.1,
                    r.primary_changed_pct,
                    r.reflection_changed_pct,
                    f1(r.psnr),
                    r.disc_bits
                );
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
        let row = |table: &str, extra: String, f: &[f64; 11]| {
            let keys = [
                "fps",
                "usage_trav",
                "usage_list",
                "usage_transf",
                "usage_int",
                "hit_trav",
                "hit_list",
                "hit_transf",
                "mb_s_core",
                "mb_s_shading",
                "mb_s_total",
            ];
            let body: Vec<String> = keys.iter().zip(f).map(|(k, v)| format!("\"{k}\":{}", num(*v))).collect();
            format!("{{\"table\":\"{table}\",\"scene\":{}{extra},{}}}", json_str(&self.scene), body.join(","))
        };
        for (table, rows) in [("saarcor_table3", &self.table3), ("saarcor_table4", &self.table4)] {
            for r in rows {
                let paper = match table {
                    "saarcor_table3" => paper::table3_of(&self.scene).filter(|_| r.size == (512, 384)).map(|p| p.saarcor_fps),
                    _ => paper::table4_of(&self.scene).filter(|_| r.size == (1024, 768)).map(|p| p.fps),
                };
                let extra = format!(
                    ",\"paper_fps\":{},\"index\":\"{}\",\"width\":{},\"height\":{},\"cycles\":{}",
                    paper.map_or("null".into(), num),
                    r.index,
                    r.size.0,
                    r.size.1,
                    r.cycles
                );
                out.push(row(table, extra, &figures(r)));
            }
        }
        if let Some(p) = paper::table4_of(&self.scene) {
            out.push(row("saarcor_table4_paper", format!(",\"paper_scene\":\"{}\"", p.scene), &paper_figures(p)));
        }
        for r in &self.threads {
            out.push(row(
                "saarcor_threads",
                format!(",\"index\":\"{}\",\"threads\":{},\"width\":{},\"height\":{}", r.index, r.threads, r.size.0, r.size.1),
                &figures(r),
            ));
        }
        for (what, r) in &self.variants {
            out.push(row("saarcor_variant", format!(",\"index\":\"{}\",\"choice\":{}", r.index, json_str(what)), &figures(r)));
        }
        for (name, a, b, p0, p1) in paper::table1_derived() {
            out.push(format!(
                "{{\"table\":\"saarcor_table1\",\"ratio\":{},\"derived_without_traversal\":{},\"derived_full\":{},\"paper_without_traversal\":{p0},\"paper_full\":{p1}}}",
                json_str(name),
                num(a),
                num(b)
            ));
        }
        for (unit, f, kb) in paper::TABLE2 {
            out.push(format!(
                "{{\"table\":\"saarcor_table2\",\"unit\":{},\"add\":{},\"mul\":{},\"div\":{},\"cmp\":{},\"memory_kb\":{kb}}}",
                json_str(unit),
                f.add,
                f.mul,
                f.div,
                f.cmp
            ));
        }
        for (what, words) in paper::TEXT_FIGURES {
            out.push(format!("{{\"table\":\"saarcor_text\",\"figure\":{},\"the_paper\":{}}}", json_str(what), json_str(words)));
        }
        for (r, (_, what)) in paper::TABLE3.iter().zip(paper::SCENES) {
            out.push(format!(
                "{{\"table\":\"saarcor_scenes\",\"scene\":{},\"triangles\":{},\"objects\":{},\"lucent\":{}}}",
                json_str(r.scene),
                r.triangles,
                r.objects,
                json_str(what)
            ));
        }
        for r in &self.pp5 {
            out.push(format!(
                "{{\"table\":\"pixel_planes_5\",\"arithmetic\":{},\"width\":{},\"height\":{},\"primary_changed_pct\":{},\"reflection_changed_pct\":{},\"psnr_db\":{},\"discriminant_bits\":{}}}",
                json_str(&r.arith),
                r.size.0,
                r.size.1,
                num(r.primary_changed_pct),
                num(r.reflection_changed_pct),
                num(r.psnr),
                r.disc_bits
            ));
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

/// Table 4's figures of a frame, in the paper's column order: fps, usage x4, hit x3,
/// MB/s x3.
fn figures(r: &FrameModel) -> [f64; 11] {
    figures_of(r.fps, r.usage, r.hit, r.mb_s)
}

fn paper_figures(p: &paper::Table4Row) -> [f64; 11] {
    figures_of(p.fps, p.usage, p.hit, p.mb_s)
}

fn figures_of(fps: f64, usage: [f64; 4], hit: [f64; 3], mb_s: [f64; 3]) -> [f64; 11] {
    [fps, usage[0], usage[1], usage[2], usage[3], hit[0], hit[1], hit[2], mb_s[0], mb_s[1], mb_s[2]]
}

/// The kd index's row of a table, or its first (a report of the bvh alone).
fn kd_or_first(rows: &[FrameModel]) -> Option<&FrameModel> {
    rows.iter().find(|r| r.index == "kd").or_else(|| rows.first())
}

fn table4_cells(f: &[f64; 11]) -> Vec<String> {
    f.iter().enumerate().map(|(i, &v)| if i == 0 { format!("{v:.2}") } else { f1(v) }).collect()
}

/// Table 4's columns: name and whether it is a rate (compared in points, not ratios).
const FIGURE_NAMES: [(&str, bool); 11] = [
    ("fps", false),
    ("usage trav %", true),
    ("usage list %", true),
    ("usage transf %", true),
    ("usage int %", true),
    ("hit trav %", true),
    ("hit list %", true),
    ("hit transf %", true),
    ("MB/s core", false),
    ("MB/s shading", false),
    ("MB/s total", false),
];

/// Whether a modelled figure is off the paper's: more than 10 points for rates, more than
/// 25% otherwise.
fn off(i: usize, model: f64, paper: f64) -> bool {
    if FIGURE_NAMES[i].1 {
        (model - paper).abs() > 10.0
    } else {
        (model / paper - 1.0).abs() > 0.25
    }
}

impl SaarcorReport {
    /// Index `ix`'s frame rate against threads: at 32 threads over one, and at 64 over
    /// 32 (when the threads table has those rows).
    fn scaling(&self, ix: &str) -> Option<(f64, f64)> {
        let fps = |t: u32| self.threads.iter().find(|q| q.index == ix && q.threads == t).map(|q| q.fps);
        Some((fps(32)? / fps(1)?, fps(64)? / fps(32)?))
    }

    /// The figures more than 25% (rates: 10 points) from the paper's, each with the
    /// modelling choices measured against it.
    fn gaps(&self, s: &mut String, p: &paper::Table4Row, kd: &FrameModel) {
        let (m, pf) = (figures(kd), paper_figures(p));
        let _ = writeln!(s, "\n### Where the kd model and the paper differ (more than 25%, rates 10 points)\n");
        if !self.variants.is_empty() {
            let _ = writeln!(s, "The kd frame under other modelling choices, each changed alone (measured):\n\n| choice | fps | usage trav % | usage list % | usage transf % | usage int % | hit trav % | hit list % | hit transf % | MB/s core | MB/s shading | MB/s total |\n|---|---|---|---|---|---|---|---|---|---|---|---|");
            let _ = writeln!(s, "| the model as above | {} |", table4_cells(&m).join(" | "));
            for (what, f) in &self.variants {
                let _ = writeln!(s, "| {} | {} |", what, table4_cells(&figures(f)).join(" | "));
            }
            let _ = writeln!(s, "| the paper | {} |", table4_cells(&pf).join(" | "));
        }
        // The work behind the usages: per packet, from busy cycles (the model) and from
        // usage x cycles of a frame (the paper: 90 MHz / fps).
        let packets = kd.packets.max(1) as f64;
        let rays = 4.0 * packets;
        let paper_cycles = 90e6 / p.fps;
        let paper_busy = |u: usize| p.usage[u] / 100.0 * paper_cycles;
        let _ = writeln!(
            s,
            "\nThe work behind the usages, per 2x2 packet of the frame (the paper's: its usage times its frame's cycles, 90 MHz / fps, over the same {} packets):\n\n| work | model | the paper | model / paper |\n|---|---|---|---|",
            kd.packets
        );
        for (what, u, per) in [
            ("traversal steps a packet", 0, packets),
            ("list entries a packet", 1, packets),
            ("transformation steps a packet", 2, packets),
            ("triangle tests a ray", 3, rays),
        ] {
            let (mv, pv) = (kd.busy[u] as f64 / per, paper_busy(u) / per);
            let _ = writeln!(s, "| {what} | {mv:.1} | {pv:.1} | {:.2} |", mv / pv);
        }
        let _ = writeln!(
            s,
            "| traversal steps a triangle test | {:.2} | {:.2} | {:.2} |",
            kd.busy[0] as f64 / kd.busy[3].max(1) as f64,
            paper_busy(0) / paper_busy(3),
            (kd.busy[0] as f64 / kd.busy[3].max(1) as f64) / (paper_busy(0) / paper_busy(3))
        );
        let _ = writeln!(s, "\n| figure | model | paper | the choice that moves it most toward the paper | there |\n|---|---|---|---|---|");
        let mut any = false;
        for i in 0..11 {
            if !off(i, m[i], pf[i]) {
                continue;
            }
            any = true;
            let dist = |v: f64| if FIGURE_NAMES[i].1 { (v - pf[i]).abs() } else { (v / pf[i]).ln().abs() };
            let best = self
                .variants
                .iter()
                .map(|(w, f)| (w.as_str(), figures(f)[i]))
                .filter(|&(_, v)| dist(v) < 0.9 * dist(m[i]))
                .min_by(|a, b| dist(a.1).total_cmp(&dist(b.1)));
            let (w, v) = best.map_or(("none of the choices measured closes a tenth of the gap", "-".to_string()), |(w, v)| (w, f1(v)));
            let _ = writeln!(s, "| {} | {} | {} | {w} | {v} |", FIGURE_NAMES[i].0, f1(m[i]), f1(pf[i]));
        }
        if !any {
            let _ = writeln!(s, "| (none) | | | | |");
        }
    }

    /// The paper's text figures beside the model's.
    fn text_figures(&self, s: &mut String) {
        let _ = writeln!(s, "\n### The paper's other figures\n\n| figure | the paper | the model |\n|---|---|---|");
        let kd3 = kd_or_first(&self.table3);
        let kd4 = kd_or_first(&self.table4);
        let flops = f64::from(paper::TABLE2_TOTAL.0.total()) * 90e6;
        for (what, words) in paper::TEXT_FIGURES {
            let model = match what {
                "clock" => "90 MHz".to_string(),
                "FLOPs" => format!("Table 2's {} units at 90 MHz: {:.2} billion", paper::TABLE2_TOTAL.0.total(), flops / 1e9),
                "rays per second" => kd3.map_or("-".into(), |r| {
                    format!("{}: {:.1}M at 512x384 ({:.2} fps)", r.index, r.fps * f64::from(r.size.0) * f64::from(r.size.1) / 1e6, r.fps)
                }),
                "threads" => kd3.and_then(|r| self.scaling(r.index)).map_or("-".into(), |(x32, x64)| {
                    format!("32 threads {x32:.1}x one; 64 {:+.0}% over 32 (latencies chosen to match)", 100.0 * (x64 - 1.0))
                }),
                "caches" => format!("{:?} KB, 512 items each", [4, 2, 6]),
                "bandwidth" => kd4.map_or("-".into(), |r| {
                    format!("{}: {:.0} MB/s total at {:.2} fps (core {:.0})", r.index, r.mb_s[2], r.fps, r.mb_s[0])
                }),
                _ => "28 B per hit ray (used)".to_string(),
            };
            let _ = writeln!(s, "| {what} | {} | {} |", words.replace('|', "/"), model);
        }
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
        if let Some(r) = kd_or_first(&self.table4) {
            let mut series = Vec::new();
            for (i, name) in ["traversal", "list", "transformation"].iter().enumerate() {
                series.push((*name, r.sweep.iter().map(|&(kb, v)| (kb as f64, v[i])).collect::<Vec<_>>()));
            }
            let _ = write!(h, "<h3>Hit rate against cache size ({} index, direct mapped)</h3>", r.index);
            h += &crate::charts::hit_rate_chart(&series);
        }
        h += "<h3>Unit usage</h3>";
        let mut bars: Vec<(String, [f64; 4])> =
            self.table4.iter().map(|r| (format!("{} {}x{}", r.index, r.size.0, r.size.1), r.usage)).collect();
        if let Some(p) = paper::table4_of(&self.scene) {
            bars.push((format!("the paper ({})", p.scene), p.usage));
        }
        h += &crate::charts::usage_chart(&bars);
        let mut lines = Vec::new();
        for ix in ["bvh", "kd"] {
            let one = self.threads.iter().find(|q| q.index == ix && q.threads == 1).map(|q| q.fps);
            let pts: Vec<(f64, f64)> =
                self.threads.iter().filter(|q| q.index == ix).filter_map(|q| one.map(|o| (f64::from(q.threads), q.fps / o))).collect();
            if !pts.is_empty() {
                lines.push((ix, pts));
            }
        }
        if !lines.is_empty() {
            h += "<h3>Frame rate against threads (512x384)</h3>";
            h += &crate::charts::threads_chart(&lines);
        }
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
        let (sh, l, measured, formula) = rend3r_machine::cycles::PAPER_MEASURED;
        out.push(format!(
            "{{\"table\":\"rend3r_measured_frame\",\"shapes\":{sh},\"lights\":{l},\"paper_cycles\":{measured},\"formula_cycles\":{formula}}}"
        ));
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

    /// The gaps table names, for each figure off the paper's, the measured choice that
    /// closes most of its gap, and says so when none closes a tenth of it.
    #[test]
    fn gaps_name_the_closest_choice() {
        let kd = |fps: f64, trav: f64, hit_list: f64| FrameModel {
            size: (1024, 768),
            index: "kd",
            fps,
            usage: [trav, 25.0, 51.0, 28.0],
            hit: [98.0, hit_list, 78.0],
            mb_s: [135.0, 132.0, 267.0],
            packets: 196_608,
            busy: [1, 1, 1, 1, 0],
            ..FrameModel::default()
        };
        let rep = SaarcorReport {
            scene: "conference.obj".into(),
            table4: vec![kd(5.7, 40.0, 95.0)],
            variants: vec![("choice A".into(), kd(5.7, 80.0, 94.0)), ("choice B".into(), kd(5.7, 60.0, 95.0))],
            ..SaarcorReport::default()
        };
        let md = rep.markdown();
        assert!(md.contains("| usage trav % | 40.0 | 89.0 | choice A | 80.0 |"), "{md}");
        assert!(md.contains("| hit list % | 95.0 | 63.0 | none of the choices measured closes a tenth of the gap | - |"), "{md}");
        assert!(!md.contains("| fps | 5.7"), "{md}");
        assert!(md.contains("| the paper | 1024x768 | 5.70 | 89.0 |"), "{md}");
    }

    #[test]
    fn markdown_tables_become_html() {
        let h = md_to_html_tables("## T\n\n| a | b |\n|---|---|\n| 1 | <2> |\n\n- x");
        assert_eq!(h, "<h2>T</h2><table><tr><td>a</td><td>b</td></tr><tr><td>1</td><td>&lt;2&gt;</td></tr></table><li>x</li>");
        assert_eq!(json_str("a\"b\n"), "\"a\\\"b\\u000a\"");
    }
}
