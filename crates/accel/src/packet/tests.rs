use super::*;

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
            unsafe { avx::transpose_rays(&rays[..n], &mut got) };
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
