//! What SaarCOR's paper prints (Schmittler, Woop, Wagner, Paul, Slusallek, "Realtime Ray
//! Tracing of Dynamic Scenes on an FPGA Chip", Graphics Hardware 2004), as data: its
//! Tables 1-4 and the figures of its text, so that every one stands beside lucent's model
//! in `lucent report`. And the floating-point units of its four designs counted here from
//! the algorithms they name, to derive Table 1 as the paper did.

/// One row of Table 3 (512×384, primary rays, textured shading).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table3Row {
    /// Scene.
    pub scene: &'static str,
    /// Triangles.
    pub triangles: u64,
    /// Dynamic objects.
    pub objects: u32,
    /// SaarCOR's frames per second (one pipeline at 90 MHz).
    pub saarcor_fps: f64,
    /// OpenRT's (SSE, Pentium-4 2.66 GHz).
    pub openrt_fps: f64,
    /// SaarCOR over OpenRT.
    pub speedup: f64,
}

/// Table 3 as printed.
pub const TABLE3: [Table3Row; 9] = [
    Table3Row { scene: "Scene6", triangles: 806, objects: 1, saarcor_fps: 60.8, openrt_fps: 12.9, speedup: 4.7 },
    Table3Row { scene: "Castle", triangles: 20_891, objects: 8, saarcor_fps: 23.8, openrt_fps: 9.2, speedup: 2.6 },
    Table3Row { scene: "Office", triangles: 34_312, objects: 1, saarcor_fps: 48.9, openrt_fps: 10.4, speedup: 4.7 },
    Table3Row { scene: "Quake3", triangles: 39_424, objects: 1, saarcor_fps: 33.6, openrt_fps: 11.1, speedup: 3.0 },
    Table3Row { scene: "Quake3-p", triangles: 52_790, objects: 17, saarcor_fps: 26.7, openrt_fps: 7.9, speedup: 3.4 },
    Table3Row { scene: "UT2003", triangles: 52_479, objects: 1, saarcor_fps: 25.4, openrt_fps: 8.0, speedup: 3.2 },
    Table3Row { scene: "Conference", triangles: 282_805, objects: 54, saarcor_fps: 22.1, openrt_fps: 8.1, speedup: 2.7 },
    Table3Row { scene: "Terrain", triangles: 10_469_866, objects: 264, saarcor_fps: 15.9, openrt_fps: 3.5, speedup: 4.5 },
    Table3Row { scene: "SunCOR", triangles: 187_145_136, objects: 5622, saarcor_fps: 32.1, openrt_fps: 7.5, speedup: 4.3 },
];

/// One row of Table 4 (1024×768, primary rays, bilinear-filtered textures).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Table4Row {
    /// Scene.
    pub scene: &'static str,
    /// Frames per second.
    pub fps: f64,
    /// Unit usage, percent: traversal, list, transformation, intersection.
    pub usage: [f64; 4],
    /// Cache hit rates, percent: traversal, list, transformation.
    pub hit: [f64; 3],
    /// External bandwidth, MB/s: DynRTC (the core's cache misses), shading, total.
    pub mb_s: [f64; 3],
}

/// Table 4 as printed (Office's total is printed as 246, its shading column's figure).
pub const TABLE4: [Table4Row; 9] = [
    Table4Row { scene: "Scene6", fps: 15.3, usage: [68.0, 16.0, 85.0, 41.0], hit: [99.0, 97.0, 99.0], mb_s: [8.0, 218.0, 226.0] },
    Table4Row { scene: "Castle", fps: 5.9, usage: [73.0, 18.0, 74.0, 48.0], hit: [99.0, 82.0, 94.0], mb_s: [50.0, 138.0, 188.0] },
    Table4Row { scene: "Office", fps: 12.4, usage: [76.0, 16.0, 72.0, 36.0], hit: [99.0, 71.0, 90.0], mb_s: [69.0, 246.0, 246.0] },
    Table4Row { scene: "Quake3", fps: 8.5, usage: [87.0, 15.0, 45.0, 21.0], hit: [99.0, 49.0, 79.0], mb_s: [104.0, 197.0, 301.0] },
    Table4Row { scene: "Quake3-p", fps: 6.8, usage: [92.0, 13.0, 35.0, 16.0], hit: [99.0, 66.0, 82.0], mb_s: [65.0, 157.0, 222.0] },
    Table4Row { scene: "UT2003", fps: 6.5, usage: [82.0, 19.0, 66.0, 42.0], hit: [98.0, 63.0, 86.0], mb_s: [105.0, 152.0, 257.0] },
    Table4Row { scene: "Conference", fps: 5.7, usage: [89.0, 25.0, 51.0, 28.0], hit: [98.0, 63.0, 78.0], mb_s: [135.0, 132.0, 267.0] },
    Table4Row { scene: "Terrain", fps: 4.2, usage: [80.0, 27.0, 34.0, 18.0], hit: [97.0, 27.0, 43.0], mb_s: [283.0, 98.0, 381.0] },
    Table4Row { scene: "SunCOR", fps: 8.7, usage: [46.0, 36.0, 29.0, 12.0], hit: [90.0, 2.0, 6.0], mb_s: [513.0, 202.0, 715.0] },
];

/// Floating-point units of one unit or design: additions, multiplications, divisions,
/// comparisons.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct FpUnits {
    /// Adders (and subtractors).
    pub add: u32,
    /// Multipliers.
    pub mul: u32,
    /// Dividers (reciprocals).
    pub div: u32,
    /// Comparators.
    pub cmp: u32,
}

impl FpUnits {
    /// All four kinds together.
    #[must_use]
    pub fn total(self) -> u32 {
        self.add + self.mul + self.div + self.cmp
    }

    /// The sum of two.
    #[must_use]
    pub fn plus(self, o: Self) -> Self {
        Self { add: self.add + o.add, mul: self.mul + o.mul, div: self.div + o.div, cmp: self.cmp + o.cmp }
    }
}

/// Table 2 as printed: (unit, floating-point units, internal memory KB).
pub const TABLE2: [(&str, FpUnits, f64); 6] = [
    ("Traversal", FpUnits { add: 4, mul: 0, div: 4, cmp: 13 }, 44.5),
    ("Mailboxed List", FpUnits { add: 0, mul: 0, div: 0, cmp: 0 }, 0.8),
    ("Transformation", FpUnits { add: 9, mul: 9, div: 0, cmp: 0 }, 9.3),
    ("Intersection", FpUnits { add: 3, mul: 2, div: 1, cmp: 0 }, 0.0),
    ("DynRTC-Cache", FpUnits { add: 0, mul: 0, div: 0, cmp: 0 }, 15.6),
    ("Shader", FpUnits { add: 0, mul: 0, div: 0, cmp: 0 }, 4.8),
];

/// Table 2's printed total.
pub const TABLE2_TOTAL: (FpUnits, f64) = (FpUnits { add: 16, mul: 11, div: 5, cmp: 13 }, 75.0);

/// Table 1 as printed: (ratio, without traversal %, full design %).
pub const TABLE1: [(&str, f64, f64); 3] =
    [("RTDyn1 / RTstatic", 66.0, 75.0), ("RTDyn1 / RTDyn2", 46.0, 57.0), ("RTDyn1 / RTDyn3", 23.0, 32.0)];

/// The units of the paper's four designs, counted here from the algorithms it names
/// (operations of one fully pipelined test; comparisons of signs and ranges counted as
/// comparators only in the traversal unit, as Table 2 does): (name, what it is, units).
pub const DESIGN_UNITS: [(&str, &str, FpUnits); 6] = [
    ("K", "traversal unit, 4 rays a step (Table 2)", FpUnits { add: 4, mul: 0, div: 4, cmp: 13 }),
    ("T", "transformation: one 3x3 matrix-vector product and a vector addition (Table 2)", FpUnits { add: 9, mul: 9, div: 0, cmp: 0 }),
    ("I", "unit-triangle test: t = -o'z/d'z, u = o'x + t d'x, v = o'y + t d'y, u + v (Table 2)", FpUnits { add: 3, mul: 2, div: 1, cmp: 0 }),
    (
        "Iw",
        "Wald's projection test [Wal04]: the denominator (2 mul, 2 add, 1 div), t (3 mul, 3 add), the projected hit (2 mul, 2 add), two barycentrics (4 mul, 4 add), their sum (1 add)",
        FpUnits { add: 12, mul: 11, div: 1, cmp: 0 },
    ),
    (
        "Ip",
        "Plücker test [Eri97] from a dynamic triangle's vertices: 3 edges' coordinates (18 mul, 18 add), the ray's (6 mul, 3 add), 3 side products (18 mul, 15 add), the plane and t (12 mul, 10 add, 1 div)",
        FpUnits { add: 46, mul: 54, div: 1, cmp: 0 },
    ),
    (
        "S",
        "shading unit's ray geometry: the hit point (3 mul, 3 add), N.D (3 mul, 2 add), the reflection D - 2cN (4 mul, 3 add), the shadow direction (3 add)",
        FpUnits { add: 11, mul: 10, div: 0, cmp: 0 },
    ),
];

fn unit(name: &str) -> FpUnits {
    DESIGN_UNITS.iter().find(|u| u.0 == name).map_or_else(FpUnits::default, |u| u.2)
}

/// A design's units without and with the traversal unit: RTDyn1 = T + I, RTDyn2 =
/// T + S + Iw, RTDyn3 = T + S + Ip, RTstatic = S + Iw (the paper's Section 2.3).
#[must_use]
pub fn design(name: &str) -> (FpUnits, FpUnits) {
    let parts: &[&str] = match name {
        "RTDyn1" => &["T", "I"],
        "RTDyn2" => &["T", "S", "Iw"],
        "RTDyn3" => &["T", "S", "Ip"],
        _ => &["S", "Iw"],
    };
    let without = parts.iter().fold(FpUnits::default(), |a, p| a.plus(unit(p)));
    (without, without.plus(unit("K")))
}

/// Table 1 derived from [`DESIGN_UNITS`]: (ratio, without traversal %, full %, the
/// paper's two figures).
#[must_use]
pub fn table1_derived() -> Vec<(&'static str, f64, f64, f64, f64)> {
    let (d1, d1k) = design("RTDyn1");
    TABLE1
        .iter()
        .map(|&(name, p0, p1)| {
            let other = name.rsplit(' ').next().unwrap_or("RTstatic");
            let (o, ok) = design(other);
            let pct = |a: FpUnits, b: FpUnits| 100.0 * f64::from(a.total()) / f64::from(b.total().max(1));
            (name, pct(d1, o), pct(d1k, ok), p0, p1)
        })
        .collect()
}

/// What the paper's two Table 1 columns imply of its own traversal unit K, as a
/// fraction of RTDyn1's units without traversal D1: from the RTstatic row's r0 = D1/X
/// and r1 = (D1 + K)/(X + K), K/D1 = (r1/r0 - 1) / (1 - r1).
#[must_use]
pub fn table1_implied_traversal() -> f64 {
    let (_, r0, r1) = TABLE1[0];
    let (r0, r1) = (r0 / 100.0, r1 / 100.0);
    (r1 / r0 - 1.0) / (1.0 - r1)
}

/// The figures of the paper's text that the model has a counterpart for: (what, the
/// paper's words).
pub const TEXT_FIGURES: [(&str, &str); 7] = [
    ("clock", "\"The prototype runs at a frequency of 90 MHz\""),
    ("FLOPs", "\"delivers a total of 4 billion FLOPs\""),
    ("rays per second", "\"our simple FPGA prototype already achieves 3M to 12M rays per second\""),
    ("threads", "\"Multi-threading increases performance almost linear up to 32 threads per DynRTP. Using 64 threads further improves performance by only about 10%\""),
    ("caches", "\"tiny caches of only 4, 2 and 6 KB for traversal, list, and transformation\" (512 items each, Table 2's caption)"),
    ("bandwidth", "\"the external bandwidth in total is small (mostly well below 300 MB/s, ignoring the fixed 135 MB/s required for frame buffer readout\"; 1 GB/s available to the DynRTC"),
    ("shading bytes", "\"only a small amount of shading data is required (28 byte per ray with bilinear texture filtering)\""),
];

/// The paper's scenes and what lucent has of each: (scene, lucent's, why not).
pub const SCENES: [(&str, &str); 9] = [
    ("Scene6", "not available: Slusallek's group's test room; no public copy found (shared/scenes/README.md)"),
    ("Castle", "not available: a commercial game level [Act02], not public"),
    ("Office", "not available: no public copy found"),
    ("Quake3", "not available: id Software's game data [Id-99], not redistributable"),
    ("Quake3-p", "not available: Quake3 with 16 players and monsters, the same game data"),
    ("UT2003", "not available: Epic's game data [Epi03], not redistributable"),
    ("Conference", "shared/scenes/conference: Grynberg and Ward's room in McGuire's 331,179-triangle version (the paper's has 282,805 in 54 objects); one object as read, 54 with --objects"),
    ("Terrain", "not available: the paper's 10.5M-triangle terrain with trees has no public copy"),
    ("SunCOR", "--demo sunflowers: 5,622 instances of a 31,904-triangle sunflower on a 2-triangle ground (the paper's has 33,288)"),
];

/// The paper's Table 3 row of a scene lucent has, by file or demo name.
#[must_use]
pub fn table3_of(scene: &str) -> Option<&'static Table3Row> {
    let key = paper_name(scene)?;
    TABLE3.iter().find(|r| r.scene == key)
}

/// The paper's Table 4 row of a scene lucent has, by file or demo name.
#[must_use]
pub fn table4_of(scene: &str) -> Option<&'static Table4Row> {
    let key = paper_name(scene)?;
    TABLE4.iter().find(|r| r.scene == key)
}

/// The paper's name of a scene lucent has.
#[must_use]
pub fn paper_name(scene: &str) -> Option<&'static str> {
    let s = scene.to_lowercase();
    if s.contains("conference") {
        Some("Conference")
    } else if s.contains("sunflower") || s.contains("suncor") {
        Some("SunCOR")
    } else {
        None
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The printed tables hold together: Table 2's rows sum to its total, Table 3's
    /// speed-ups are its two columns' ratio to the printed digit, and Table 4's totals
    /// are its two bandwidth columns (but Office's, printed as its shading figure).
    #[test]
    fn printed_tables_are_consistent() {
        let sum = TABLE2.iter().fold(FpUnits::default(), |a, r| a.plus(r.1));
        assert_eq!(sum, TABLE2_TOTAL.0);
        let kb: f64 = TABLE2.iter().map(|r| r.2).sum();
        assert!((kb - TABLE2_TOTAL.1).abs() < 1e-9);
        for r in TABLE3 {
            assert!((r.saarcor_fps / r.openrt_fps - r.speedup).abs() < 0.06, "{}", r.scene);
        }
        for r in TABLE4 {
            if r.scene != "Office" {
                assert!((r.mb_s[0] + r.mb_s[1] - r.mb_s[2]).abs() < 1.5, "{}", r.scene);
            }
        }
        // 45 floating-point units at 90 MHz: the "4 billion FLOPs".
        assert!((f64::from(TABLE2_TOTAL.0.total()) * 90e6 - 4.05e9).abs() < 1e6);
    }

    /// Table 1 from the counted units: RTDyn1 is cheapest and the Plücker design dearest,
    /// as printed; the paper's own columns imply a traversal unit of about half RTDyn1's
    /// other units.
    #[test]
    fn table1_derivation() {
        let t = table1_derived();
        assert_eq!(t.len(), 3);
        for &(name, a, b, _, _) in &t {
            assert!(a < 100.0 && b < 100.0 && b > a, "{name}: {a} {b}");
        }
        assert!(t[2].1 < t[1].1 && t[1].1 < t[0].1);
        assert_eq!(design("RTDyn1").0.total(), 24);
        let k = table1_implied_traversal();
        assert!((k - 0.545).abs() < 0.01, "{k}");
        assert_eq!(paper_name("/x/conference.obj.gz"), Some("Conference"));
        // The scenes' notes stand in Table 3's order (the report pairs them by place).
        assert!(SCENES.iter().zip(TABLE3).all(|(s, r)| s.0 == r.scene));
        assert!(TABLE4.iter().zip(TABLE3).all(|(a, b)| a.scene == b.scene));
        assert_eq!(table4_of("sunflowers").map(|r| r.fps), Some(8.7));
    }
}
