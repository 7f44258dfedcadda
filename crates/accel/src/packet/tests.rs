use super::core::*;
use super::mesh::*;
use super::rays::*;

/// The AVX2 transpose puts every ray of a partial or full group where `RayBlock::set`
/// does, and empties the other lanes.
#[test]
fn transposed_rays_match_lane_by_lane_loads() {
    #[cfg(target_arch = "x86_64")]
    if crate::simd::avx2() {
        let rays: Vec<Ray> = (0..8)
            .map(|i| {
                let f = i as f32;
                Ray { org: Vec3::new(f, f + 0.1, f + 0.2), dir: Vec3::new(-f, 1.0 + f, 0.5 * f), tmin: 0.01 * f, tmax: 10.0 + f }
            })
            .collect();
        for n in 1..=8 {
            let mut want = RayBlock::EMPTY;
            for (l, r) in rays[..n].iter().enumerate() {
                want.set(l, r);
            }
            let mut got = RayBlock::EMPTY;
            // SAFETY: AVX2 was detected above.
            unsafe { super::avx::transpose_rays(&rays[..n], &mut got) };
            assert_eq!(got, want, "{n} rays");
        }
    }
}

/// A packet of eight rays from one tile, with the directions `dir(i)`.
fn packet_of(dir: impl Fn(usize) -> Vec3) -> Packet {
    let mut b = RayBlock::EMPTY;
    for l in 0..LANES {
        let org = Vec3::new(0.01 * l as f32, 0.0, 0.0);
        b.set(l, &Ray { org, dir: dir(l), tmin: 0.0, tmax: f32::INFINITY });
    }
    let (mut p, mut h) = Packet::empty();
    p.load_blocks_into(&[b], &mut h);
    p
}

/// Rays whose unit directions lie close together are worth a packet, however long
/// their directions; rays scattered over an octant (diffuse bounces) are not; a lane
/// with a zero direction holds no ray and does not count.
#[test]
fn scattered_directions_are_not_worth_a_packet() {
    let worth = |p: &Packet| p.interval(&p.valid).is_some_and(|iv| iv.worth(lane_count(&p.valid), 1.0));
    let near = |l: usize| Vec3::new(0.3 + 0.004 * l as f32, 0.5, 0.8).normalize();
    assert!(worth(&packet_of(near)));
    for scale in [1e-3, 100.0, 1e6] {
        assert!(worth(&packet_of(|l| near(l) * scale)), "scale {scale}");
    }
    // One octant, cosine-like scatter.
    let scattered = |l: usize| Vec3::new(0.1 + 0.12 * l as f32, 1.0 - 0.1 * l as f32, 0.2 + 0.05 * (l % 3) as f32).normalize();
    assert!(!worth(&packet_of(scattered)));
    // A zero direction is no ray (not a valid lane): the others still make a packet.
    let p = packet_of(|l| if l == 3 { Vec3::ZERO } else { near(l) });
    assert_eq!(lane_count(&p.valid), 7);
    assert!(worth(&p));
    // The limit itself: a spread of twice the limit in one component is too much.
    let wide = |l: usize| Vec3::new(0.5 + 2.0 * MAX_DIR_SPREAD * (l as f32 / 7.0), 0.5, 0.7).normalize();
    assert!(!worth(&packet_of(wide)));
}

/// Everything a traversal reports, by kind and address.
#[derive(Default)]
struct Reads {
    nodes: std::collections::BTreeSet<usize>,
    node_reads: usize,
    lists: std::collections::BTreeSet<usize>,
    list_reads: usize,
    transforms: usize,
    tri_reports: usize,
    shapes: usize,
}

impl Counters for Reads {
    fn node(&mut self) {}
    fn items(&mut self, _: u32) {}
    fn node_read(&mut self, addr: usize, _: usize) {
        self.nodes.insert(addr);
        self.node_reads += 1;
    }
    fn list_read(&mut self, addr: usize, _: usize) {
        self.lists.insert(addr);
        self.list_reads += 1;
    }
    fn transform(&mut self, _: usize, _: usize) {
        self.transforms += 1;
    }
    fn triangles(&mut self, _: usize, _: usize, n: u32) {
        assert_eq!(n, 4, "a 4-triangle group");
        self.tri_reports += 1;
    }
    fn shape(&mut self, _: usize, _: usize) {
        self.shapes += 1;
    }
}

/// Hand-counted packet work against the single-ray kernels on a tiny two-level scene: a
/// coherent packet of four rays into one translated instance reads each node and list
/// entry once for all four (the nodes the four single rays read), carries each ray into
/// object space once and tests each ray against the triangle group once; four rays into a
/// sphere instance are four shape tests. The counted walk gives the fast walk's answers.
#[test]
fn packet_counters_by_hand() {
    let tri = MeshBvh::build(&[Vec3::ZERO, Vec3::X, Vec3::Y], &[[0, 1, 2]], crate::MeshOptions::default()).expect("mesh");
    let at = |x: f32| Affine3A::from_translation(Vec3::new(x, 0.0, 0.0));
    let tl = TwoLevel::new(
        vec![Geometry::Mesh(tri), Geometry::Shape(Shape::Sphere)],
        vec![crate::tlas::Instance::new(0, at(5.0)), crate::tlas::Instance::new(0, at(-5.0)), crate::tlas::Instance::new(1, at(0.0))],
    )
    .expect("scene");
    let o = Vec3::new(5.2, 0.2, 3.0);
    // No direction component is zero: a ray parallel to an axis turns that axis's
    // interval culling off for the packet (`PARALLEL_INV`), which this count is not about.
    let rays: [Ray; 4] = std::array::from_fn(|l| Ray::new(o, Vec3::new(0.01 * (l + 1) as f32, 0.005 * (l + 1) as f32, -1.0)));
    let mut single = Reads::default();
    for r in &rays {
        assert!(tl.intersect_counted(r, &mut single).is_some());
    }
    let mut packet = Reads::default();
    let mut got = [None; 4];
    tl.intersect_packet_counted(&rays, &mut got, &mut packet);
    let mut fast = [None; 4];
    tl.intersect_packet(&rays, &mut fast);
    assert_eq!(got, fast);
    assert!(got.iter().all(|h| h.is_some_and(|h| h.inst == 0)));
    assert_eq!(packet.nodes, single.nodes, "the nodes the single rays read");
    assert_eq!(4 * packet.node_reads, single.node_reads, "each node once per packet");
    assert_eq!(packet.lists, single.lists);
    assert_eq!(4 * packet.list_reads, single.list_reads, "each list entry once per packet");
    assert_eq!(packet.transforms, single.transforms);
    assert_eq!(packet.tri_reports, single.tri_reports);
    assert!(packet.transforms >= 4 && packet.tri_reports >= 4);
    // Into the sphere: four shape tests, no transformation (identity), no triangle.
    let rays: [Ray; 4] = std::array::from_fn(|l| Ray::new(Vec3::new(0.1 * l as f32, 0.0, 3.0), -Vec3::Z));
    let mut packet = Reads::default();
    tl.intersect_packet_counted(&rays, &mut got, &mut packet);
    assert!(got.iter().all(|h| h.is_some_and(|h| h.inst == 2)));
    assert_eq!((packet.shapes, packet.transforms, packet.tri_reports), (4, 0, 0));
    // Occlusion: the same answers as the fast kernel, each ray's test counted.
    let shadow: [Ray; 4] = std::array::from_fn(|l| Ray { tmax: 10.0, ..Ray::new(o, Vec3::new(0.01 * l as f32, 0.0, -1.0)) });
    let mut packet = Reads::default();
    let mut occ = [false; 4];
    tl.occluded_packet_counted(&shadow, &mut occ, &mut packet);
    let mut fast = [false; 4];
    tl.occluded_packet(&shadow, &mut fast);
    assert_eq!(occ, fast);
    assert_eq!(occ, [true; 4]);
    assert_eq!(packet.tri_reports, 4);
}

/// The counted packet walk finds the fast packet kernels' hits on a random scene of many
/// instances (coherent tiles and scattered rays), and a packet with a hit reported the
/// triangle tests that found it.
#[test]
fn counted_packets_match_fast_packets() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand::rngs::StdRng::seed_from_u64(36);
    let p: Vec<Vec3> =
        (0..300).map(|_| Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))).collect();
    let idx: Vec<[u32; 3]> = (0..100).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let mesh = MeshBvh::build(&p, &idx, crate::MeshOptions::default()).expect("mesh");
    let inst: Vec<_> = (0..40)
        .map(|i| crate::tlas::Instance::new(0, Affine3A::from_translation(Vec3::new((i % 8) as f32 * 2.5, (i / 8) as f32 * 2.5, 0.0))))
        .collect();
    let tl = TwoLevel::new(vec![Geometry::Mesh(mesh)], inst).expect("scene");
    for k in 0..400 {
        let o = Vec3::new(8.0, 5.0, 20.0);
        let coherent = k % 2 == 0;
        let base = Vec3::new(rng.random_range(-0.5..0.5), rng.random_range(-0.3..0.3), -1.0);
        let rays: Vec<Ray> = (0..16)
            .map(|l| {
                let d = if coherent {
                    base + Vec3::new(0.002 * (l % 4) as f32, 0.002 * (l / 4) as f32, 0.0)
                } else {
                    Vec3::new(rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0), rng.random_range(-1.0..1.0))
                };
                Ray::new(o, d)
            })
            .collect();
        let mut got = vec![None; 16];
        let mut c = Reads::default();
        tl.intersect_packet_counted(&rays, &mut got, &mut c);
        let mut fast = vec![None; 16];
        tl.intersect_packet(&rays, &mut fast);
        for l in 0..16 {
            assert_eq!(got[l].map(|h| (h.t, h.inst)), fast[l].map(|h| (h.t, h.inst)), "packet {k} lane {l}");
        }
        if got.iter().any(Option::is_some) {
            assert!(c.tri_reports > 0 && c.node_reads > 0, "packet {k}");
        }
    }
}
