//! The Mitsuba XML reader: what it reads, and errors at line:column for what it cannot.

use glam::Vec3;
use lucent_scene::{parse_mitsuba, parse_mitsuba_with, AovKind, Bsdf, ColorTex, Geom, ImportError, LightKind, Scene, ShapeKind, Sides};
use std::path::Path;

fn parse(xml: &str) -> Result<Scene, ImportError> {
    parse_mitsuba(Path::new("t.xml"), Path::new("/nonexistent"), xml)
}

fn err(xml: &str) -> String {
    match parse(xml) {
        Ok(_) => panic!("expected an error for {xml}"),
        Err(e) => e.to_string(),
    }
}

const SENSOR: &str = r#"<sensor type="perspective"><float name="fov" value="60"/>
    <transform name="to_world"><lookat origin="0,0,5" target="0,0,0" up="0,1,0"/></transform>
    <film type="hdrfilm"><integer name="width" value="200"/><integer name="height" value="100"/><rfilter type="box"/></film>
    <sampler type="independent"><integer name="sample_count" value="32"/></sampler></sensor>"#;

#[test]
fn reads_sensor_film_sampler_and_integrator() {
    let s = parse(&format!(
        r#"<scene version="3.0.0"><integrator type="path"><integer name="max_depth" value="7"/><boolean name="hide_emitters" value="true"/></integrator>{SENSOR}</scene>"#
    ))
    .expect("scene");
    let h = s.hints.expect("hints");
    assert_eq!((h.width, h.height, h.spp, h.max_depth, h.rr_depth, h.hide_emitters), (200, 100, 32, Some(7), 5, true));
    let c = s.camera.expect("camera");
    assert!((c.eye - Vec3::new(0.0, 0.0, 5.0)).length() < 1e-6 && (c.look_at - c.eye).normalize().z < -0.999);
    // fov 60 along x (Mitsuba's default axis) of a 2:1 film: tan(v/2) = tan(30°)/2.
    let want = 2.0 * (30f32.to_radians().tan() / 2.0).atan().to_degrees();
    assert!((c.vfov_deg - want).abs() < 1e-3, "{} against {want}", c.vfov_deg);
}

#[test]
fn reads_shapes_bsdfs_and_emitters() {
    let s = parse(&format!(
        r#"<scene version="3.0.0">{SENSOR}
        <default name="r" value="0.25"/>
        <bsdf type="roughconductor" id="metal"><string name="material" value="Au"/><string name="distribution" value="ggx"/><float name="alpha" value="0.2"/></bsdf>
        <shape type="sphere"><point name="center" x="1" y="2" z="3"/><float name="radius" value="$r"/><ref id="metal"/></shape>
        <shape type="rectangle"><bsdf type="twosided"><bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.2, 0.3"/></bsdf></bsdf>
            <emitter type="area"><rgb name="radiance" value="4 5 6"/></emitter></shape>
        <shape type="cube"><bsdf type="dielectric"/></shape>
        <shape type="cylinder"><float name="radius" value="0.5"/></shape>
        <emitter type="spot"><float name="cutoff_angle" value="30"/></emitter>
        <emitter type="constant"><rgb name="radiance" value="0.5"/></emitter>
        <shape type="nosuchshape"/>
        <emitter type="nosuchemitter"/>
        </scene>"#
    ))
    .expect("scene");
    // Sphere: centre and radius from $r.
    let sphere = s.instances.iter().find(|i| matches!(i.geom, Geom::Shape { kind: ShapeKind::Sphere, .. })).expect("sphere");
    assert!((Vec3::from(sphere.world_from_object.translation) - Vec3::new(1.0, 2.0, 3.0)).length() < 1e-6);
    assert!((sphere.world_from_object.matrix3.x_axis.length() - 0.25).abs() < 1e-6);
    let Geom::Shape { material, .. } = sphere.geom else { unreachable!() };
    assert!(matches!(&s.materials[material as usize].bsdf, Some(Bsdf::Conductor { rough: Some(_), .. })));
    assert_eq!(s.materials[material as usize].sides, Sides::Front, "a bare BSDF is one-sided, as in Mitsuba");
    // The rectangle: two triangles, twosided diffuse, emitting.
    let rect = s.meshes.iter().position(|m| m.name == "rectangle").expect("rectangle");
    let m = &s.materials[s.meshes[rect].material[0] as usize];
    assert_eq!(m.sides, Sides::Both);
    assert_eq!(m.emission, Vec3::new(4.0, 5.0, 6.0));
    assert!(matches!(&m.bsdf, Some(Bsdf::Diffuse { reflectance: ColorTex::Const(c) }) if *c == Vec3::new(0.1, 0.2, 0.3)));
    assert_eq!(s.meshes.iter().find(|m| m.name == "cube").expect("cube").indices.len(), 12);
    assert!(s.instances.iter().any(|i| matches!(i.geom, Geom::Shape { kind: ShapeKind::Tube, .. })));
    // Spot: Mitsuba's beam width defaults to 3/4 of the cutoff.
    let LightKind::Spot { inner, outer, .. } = s.lights[0].kind else { panic!("spot") };
    assert!((outer - 30f32.to_radians()).abs() < 1e-6 && (inner - 22.5f32.to_radians()).abs() < 1e-6);
    assert_eq!(s.environment.expect("constant").scale, Vec3::splat(0.5));
}

#[test]
fn defines_replace_defaults() {
    let xml = r#"<scene version="3.0.0"><default name="spp" value="4"/>
        <sensor type="perspective"><float name="fov" value="45"/><sampler type="independent"><integer name="sample_count" value="$spp"/></sampler></sensor></scene>"#;
    let s = parse_mitsuba_with(Path::new("t.xml"), Path::new("."), xml, &[("spp".into(), "9".into())]).expect("scene");
    assert_eq!(s.hints.expect("hints").spp, 9);
    assert_eq!(parse(xml).expect("scene").hints.expect("hints").spp, 4);
}

#[test]
fn errors_name_the_line_and_column_and_what_was_expected() {
    // Malformed XML.
    assert!(
        err("<scene version=\"3.0.0\">\n  <shape type=\"sphere\">\n</scene>").starts_with("t.xml:3:"),
        "{}",
        err("<scene>\n<shape>\n</scene>")
    );
    // Not a scene.
    assert!(err("<nothing/>").contains("expected <scene>"));
    let e = err(
        "<scene version=\"3.0.0\">\n <shape type=\"sphere\">\n  <transform name=\"to_world\"><twist/></transform>\n </shape>\n</scene>",
    );
    assert!(e.starts_with("t.xml:3:") && e.contains("expected translate, rotate, scale, matrix or lookat"), "{e}");
    let e = err(r#"<scene version="3.0.0"><shape type="sphere"><float name="radius" value="big"/></shape></scene>"#);
    assert!(e.contains("'big' is not a number"), "{e}");
    let e = err(r#"<scene version="3.0.0"><shape type="sphere"><ref id="nowhere"/></shape></scene>"#);
    assert!(e.contains("no element has id 'nowhere'"), "{e}");
    let e = err(r#"<scene version="3.0.0"><shape type="sphere"><float name="radius" value="$undefined"/></shape></scene>"#);
    assert!(e.contains("$undefined"), "{e}");
    let e = err(
        r#"<scene version="3.0.0"><shape type="sphere"><bsdf type="conductor"><string name="material" value="Kryptonite"/></bsdf></shape></scene>"#,
    );
    assert!(e.contains("Kryptonite"), "{e}");
    let e = err(
        r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="1000000000"/></film></sensor></scene>"#,
    );
    assert!(e.contains("film size"), "{e}");
    let e = err(r#"<scene version="3.0.0"><shape type="obj"><string name="filename" value="missing.obj"/></shape></scene>"#);
    assert!(e.contains("missing.obj"), "{e}");
    let e =
        err(r#"<scene version="3.0.0"><shape type="sphere"><transform name="to_world"><scale value="1e39"/></transform></shape></scene>"#);
    assert!(e.contains("not finite") || e.contains("not a number"), "{e}");
}

#[test]
fn reference_cycles_and_deep_nesting_end_in_errors() {
    // A twosided BSDF that contains a reference to itself.
    let e = err(
        r#"<scene version="3.0.0"><bsdf type="twosided" id="a"><ref id="a"/></bsdf><shape type="sphere"><ref id="a"/></shape></scene>"#,
    );
    assert!(e.contains("deep"), "{e}");
    // Thousands of nested twosided BSDFs.
    let n = 5000;
    let xml = format!(
        r#"<scene version="3.0.0"><shape type="sphere">{}<bsdf type="diffuse"/>{}</shape></scene>"#,
        r#"<bsdf type="twosided">"#.repeat(n),
        "</bsdf>".repeat(n)
    );
    assert!(err(&xml).contains("nest deeper"), "{}", err(&xml));
    // (Comments, quotes and self-closing tags do not count.)
    let ok = format!(r#"<scene version="3.0.0"><!-- <a><b><c> -->{}</scene>"#, r#"<default name="x" value="a>b"/>"#.repeat(1000));
    parse(&ok).expect("flat scene");
}

/// How MTL and glTF materials land on BSDFs (documented in `lucent_scene::bsdf`).
#[test]
fn mtl_and_gltf_materials_keep_their_parameters() {
    let shared = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/scenes");
    let shared = std::env::var("LUCENT_SCENES").map(std::path::PathBuf::from).unwrap_or(shared);
    // MTL: diffuse only (Ks 0) → Lambertian; Ks > 0 → diffuse + Beckmann lobe with α from Ns.
    let cb = lucent_scene::load(&shared.join("cornell_box_original/CornellBox-Original.obj")).expect("cornell");
    let floor = cb.materials.iter().find(|m| m.name == "floor").expect("floor");
    assert!(
        matches!(&floor.bsdf, Some(Bsdf::Diffuse { reflectance: ColorTex::Const(c) }) if (*c - Vec3::new(0.725, 0.71, 0.68)).abs().max_element() < 1e-6)
    );
    let light = cb.materials.iter().find(|m| m.name == "light").expect("light");
    assert_eq!(light.emission, Vec3::new(17.0, 12.0, 4.0));
    let kitchen = lucent_scene::load(&shared.join("bart/kitchen/kitchen_t0.obj.gz")).expect("kitchen");
    let chrome = kitchen.materials.iter().find(|m| m.name == "m4").expect("m4");
    match &chrome.bsdf {
        Some(Bsdf::DiffuseGlossy { specular, alpha, .. }) => {
            assert_eq!(*specular, Vec3::splat(0.9));
            assert!((alpha - (2.0f32 / (97.4304 + 2.0)).sqrt()).abs() < 1e-6, "{alpha}");
        }
        other => panic!("m4: {other:?}"),
    }
    // glTF: metallic-roughness with its factors, the mask's cutoff, emission.
    let g = lucent_scene::load(&shared.join("gltf-validator/test/base/data/material/valid.gltf")).expect("valid.gltf");
    let m = &g.materials[1];
    match &m.bsdf {
        Some(Bsdf::MetallicRoughness { base_color, metallic, roughness, .. }) => {
            assert_eq!(base_color.mean_guess(), Vec3::new(1.0, 0.0, 1.0));
            assert_eq!((metallic.factor(), roughness.factor()), (0.7, 0.3));
        }
        other => panic!("{other:?}"),
    }
    assert_eq!(m.alpha, lucent_scene::Alpha::Mask { cutoff: 0.4, tex: None, factor: 1.0 });
    assert_eq!(m.emission, Vec3::new(0.0, 1.0, 0.0));
    let modes = lucent_scene::load(&shared.join("gltf-validator/test/base/data/material/alpha_modes.gltf")).expect("alpha_modes.gltf");
    let alphas: Vec<_> = modes.materials[1..].iter().map(|m| m.alpha).collect();
    assert_eq!(
        alphas,
        [
            lucent_scene::Alpha::Mask { cutoff: 0.6, tex: None, factor: 1.0 },
            lucent_scene::Alpha::Mask { cutoff: 0.5, tex: None, factor: 1.0 },
            lucent_scene::Alpha::Opaque
        ]
    );
}

/// Spectra read as Mitsuba 3.9.1's RGB variants read them (its colours of the same
/// scene, from `mi.traverse`): reflectances under D65 and clamped, emission without an
/// illuminant (a uniform one is slightly pink), indices unclamped, `.spd` files.
#[test]
fn spectra_read_as_mitsuba_reads_them() {
    let dir = tempfile::tempdir().expect("tempdir");
    std::fs::write(dir.path().join("k.spd"), "# absorption\n400 3\n700 4\n").expect("spd");
    let xml = format!(
        r#"<scene version="3.0.0">{SENSOR}
        <bsdf type="diffuse" id="d"><spectrum name="reflectance" value="400:0.2, 500:0.5, 600:0.8, 700:0.3"/></bsdf>
        <bsdf type="conductor" id="c"><spectrum name="eta" value="400:1.5, 700:2.0"/><spectrum name="k" filename="k.spd"/></bsdf>
        <shape type="sphere"><ref id="d"/><emitter type="area"><spectrum name="radiance" value="5"/></emitter></shape>
        <shape type="sphere"><ref id="c"/><point name="center" x="3" y="0" z="0"/></shape>
        <emitter type="point"><spectrum name="intensity" value="400:10, 700:20"/></emitter>
        </scene>"#
    );
    let s = parse_mitsuba(&dir.path().join("t.xml"), dir.path(), &xml).expect("scene");
    let close = |a: Vec3, b: [f32; 3]| {
        assert!((a - Vec3::from(b)).abs().max_element() < 2e-5 * Vec3::from(b).max_element().max(1.0), "{a} vs {b:?}")
    };
    let m = |i: usize| {
        let Geom::Shape { material, .. } = s.instances[i].geom else { panic!("shape") };
        &s.materials[material as usize]
    };
    let Some(Bsdf::Diffuse { reflectance: ColorTex::Const(r) }) = &m(0).bsdf else { panic!("diffuse") };
    close(*r, [0.755_029, 0.641_416, 0.323_239]);
    close(m(0).emission, [6.023_97, 4.741_46, 4.544_58]);
    let Some(Bsdf::Conductor { eta, k, .. }) = &m(1).bsdf else { panic!("conductor") };
    // (lucent's conductor divides by the outside's index, air's 1.000277 by default.)
    close(*eta * 1.000_277, [1.895_09, 1.737_86, 1.560_38]);
    close(*k * 1.000_277, [3.790_17, 3.475_72, 3.120_77]);
    close(s.lights[0].color, [21.4, 14.042_4, 10.171_4]);
    let e = err(
        r#"<scene version="3.0.0"><shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" value="500:1, 400:2"/></bsdf></shape></scene>"#,
    );
    assert!(e.contains("t.xml:1:") && e.contains("wavelengths must increase"), "{e}");
}

/// Spectrum plugins: a black body's colour as Mitsuba 3.9.1's spectral variant renders an
/// emitter of it (`llvm_ad_spectral`, 65,536 samples a pixel over 16 pixels, so about
/// 0.5% noise; its RGB variants refuse black bodies); `d65` and `uniform` as its RGB
/// variants read them (white, times `scale` or `value`); `regular` and `irregular` as the
/// same samples written as pairs.
#[test]
fn spectrum_plugins() {
    let emitted = |spectrum: &str| -> Result<Vec3, String> {
        let xml = format!(r#"<scene version="3.0.0"><shape type="sphere"><emitter type="area">{spectrum}</emitter></shape></scene>"#);
        let s = parse(&xml).map_err(|e| e.to_string())?;
        Ok(s.materials.last().expect("material").emission)
    };
    for (t, mitsuba) in [
        (3000, [733.78, 349.93, 112.82]),
        (5000, [15277.1, 12095.0, 9603.3]),
        (6504, [44055.9, 41552.8, 43769.2]),
        (10000, [158561.5, 180894.3, 260343.1]),
    ] {
        let c = emitted(&format!(r#"<spectrum type="blackbody" name="radiance"><float name="temperature" value="{t}"/></spectrum>"#))
            .expect("blackbody");
        let m = Vec3::from(mitsuba);
        assert!(((c - m) / m).abs().max_element() < 0.01, "{t} K: {c} against Mitsuba's {m}");
    }
    let e = emitted(r#"<spectrum type="blackbody" name="radiance"/>"#).expect_err("no temperature");
    assert!(e.contains("t.xml:1:") && e.contains("temperature"), "{e}");
    let d65 = emitted(r#"<spectrum type="d65" name="radiance"><float name="scale" value="3"/></spectrum>"#).expect("d65");
    assert_eq!(d65, Vec3::splat(3.0));
    let uniform = emitted(r#"<spectrum type="uniform" name="radiance"><float name="value" value="5"/></spectrum>"#).expect("uniform");
    assert_eq!(uniform, Vec3::splat(5.0), "Mitsuba's RGB render of this emitter: 5, 5, 5");
    let pairs = emitted(r#"<spectrum name="radiance" value="400:10, 500:15, 600:20"/>"#).expect("pairs");
    let irregular = emitted(r#"<spectrum type="irregular" name="radiance"><string name="wavelengths" value="400, 500, 600"/><string name="values" value="10, 15, 20"/></spectrum>"#).expect("irregular");
    let regular = emitted(r#"<spectrum type="regular" name="radiance"><float name="wavelength_min" value="400"/><float name="wavelength_max" value="600"/><string name="values" value="10, 15, 20"/></spectrum>"#).expect("regular");
    assert_eq!((irregular, regular), (pairs, pairs));
    let e = emitted(r#"<spectrum type="rainbow" name="radiance"/>"#).expect_err("unknown type");
    assert!(e.contains("t.xml:1:") && e.contains("'rainbow'"), "{e}");
}

/// `<include>` (nested, relative to the including file, errors naming the included file
/// and line), `<path>` (a folder searched for files) and `<alias>`.
#[test]
fn includes_paths_and_aliases() {
    let dir = tempfile::tempdir().expect("tempdir");
    let d = dir.path();
    std::fs::create_dir_all(d.join("parts/deeper")).expect("dirs");
    std::fs::create_dir_all(d.join("meshes")).expect("dirs");
    std::fs::write(d.join("meshes/tri.obj"), "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n").expect("obj");
    std::fs::write(
        d.join("parts/materials.xml"),
        r#"<scene version="3.0.0">
    <bsdf type="diffuse" id="white"><rgb name="reflectance" value="0.8"/></bsdf>
    <alias id="white" as="paint"/>
    <include filename="deeper/light.xml"/>
</scene>"#,
    )
    .expect("materials");
    std::fs::write(
        d.join("parts/deeper/light.xml"),
        r#"<scene version="3.0.0"><emitter type="point"><rgb name="intensity" value="7"/></emitter></scene>"#,
    )
    .expect("light");
    let main = format!(
        r#"<scene version="3.0.0">{SENSOR}
    <path value="meshes"/>
    <include filename="parts/materials.xml"/>
    <shape type="obj"><string name="filename" value="tri.obj"/><ref id="paint"/></shape>
</scene>"#
    );
    let s = parse_mitsuba(&d.join("main.xml"), d, &main).expect("scene");
    assert_eq!(s.meshes.len(), 1, "the mesh found through <path>");
    let m = &s.materials[s.meshes[0].material[0] as usize];
    assert!(
        matches!(&m.bsdf, Some(Bsdf::Diffuse { reflectance: ColorTex::Const(c) }) if *c == Vec3::splat(0.8)),
        "the aliased BSDF of the included file"
    );
    assert_eq!(s.lights.len(), 1, "the light of the file the included file includes");
    assert_eq!(s.lights[0].color, Vec3::splat(7.0));

    // A cycle, a missing file, and an error inside an included file: each named where it is.
    std::fs::write(d.join("a.xml"), r#"<scene version="3.0.0"><include filename="b.xml"/></scene>"#).expect("a");
    std::fs::write(d.join("b.xml"), "<scene version=\"3.0.0\">\n  <include filename=\"a.xml\"/></scene>").expect("b");
    let e = parse_mitsuba(&d.join("a.xml"), d, &std::fs::read_to_string(d.join("a.xml")).expect("a")).expect_err("cycle").to_string();
    assert!(e.contains("b.xml:2:3") && e.contains("cycle"), "{e}");
    let e = parse(r#"<scene version="3.0.0"><include filename="nowhere.xml"/></scene>"#).expect_err("missing").to_string();
    assert!(e.contains("t.xml:1:24") && e.contains("nowhere.xml"), "{e}");
    std::fs::write(
        d.join("bad.xml"),
        "<scene version=\"3.0.0\">\n<shape type=\"sphere\"><float name=\"radius\" value=\"x\"/></shape></scene>",
    )
    .expect("bad");
    let e =
        parse_mitsuba(&d.join("m.xml"), d, r#"<scene version="3.0.0"><include filename="bad.xml"/></scene>"#).expect_err("bad").to_string();
    assert!(e.contains("bad.xml:2:") && e.contains("'x' is not a number"), "{e}");
}

/// A device or a folder named as an included file, a spectrum or a mesh is refused, not read.
#[cfg(unix)]
#[test]
fn includes_of_devices_are_refused() {
    let e = parse(r#"<scene version="3.0.0"><include filename="/dev/zero"/></scene>"#).expect_err("device").to_string();
    assert!(e.contains("not a regular file"), "{e}");
    let e = parse(r#"<scene version="3.0.0"><shape type="sphere"><bsdf type="diffuse"><spectrum name="reflectance" filename="/dev/zero"/></bsdf></shape></scene>"#)
        .expect_err("device")
        .to_string();
    assert!(e.contains("not a regular file"), "{e}");
    let e = parse(r#"<scene version="3.0.0"><shape type="obj"><string name="filename" value="/dev/zero"/></shape></scene>"#)
        .expect_err("device")
        .to_string();
    assert!(e.contains("not a regular file"), "{e}");
}

/// `.serialized` meshes Mitsuba wrote (tools/mitsuba/scenes: its material-preview meshes in
/// format version 3, rectangles of its test data in version 4), picked by `shape_index`;
/// an index past the file's meshes is an error at the shape's line.
#[test]
fn serialized_meshes_mitsuba_wrote() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/mitsuba/scenes");
    let xml = |file: &str, index: u32, extra: &str| {
        format!(
            r#"<scene version="3.0.0">
    <shape type="serialized"><string name="filename" value="{file}"/><integer name="shape_index" value="{index}"/>{extra}</shape>
</scene>"#
        )
    };
    let load = |file: &str, index: u32, extra: &str| parse_mitsuba(&dir.join("t.xml"), &dir, &xml(file, index, extra));
    let plane = load("matpreview_plane_interior.serialized", 0, "").expect("plane");
    let m = &plane.meshes[0];
    assert_eq!((m.positions.len(), m.indices.len()), (289, 512));
    assert_eq!((m.normals.values.len(), m.uvs.values.len()), (289, 289), "the plane has normals and texture coordinates");
    let inner = load("matpreview_plane_interior.serialized", 1, "").expect("interior").meshes.remove(0);
    assert!(inner.indices.len() > 1000 && inner.positions.len() != 289, "mesh 1 is another mesh");
    for (file, normals, uvs) in [
        ("rectangle_normals_uv.serialized", true, true),
        ("rectangle_uv.serialized", false, true),
        ("rectangle_normals.serialized", true, false),
    ] {
        let m = load(file, 0, "").expect(file).meshes.remove(0);
        assert_eq!((m.positions.len(), m.indices.len()), (4, 2), "{file}");
        // (A mesh without normals gets smooth ones, as in Mitsuba.)
        assert_eq!(m.normals.values.len(), 4, "{file}: normals {normals}");
        assert_eq!(m.uvs.values.len(), if uvs { 4 } else { 0 }, "{file}");
        assert!(m.positions.iter().all(|p| p.y == 0.0), "{file}: the rectangle lies in y = 0");
    }
    let flat = load("rectangle_normals.serialized", 0, r#"<boolean name="face_normals" value="true"/>"#).expect("face normals");
    assert!(flat.meshes[0].normals.values.is_empty(), "face_normals drops the file's normals");
    let e = load("matpreview_plane_interior.serialized", 2, "").expect_err("index past the meshes").to_string();
    assert!(e.contains("t.xml:2:5") && e.contains("holds 2 meshes"), "{e}");
    let e = load("serialized.xml", 0, "").expect_err("not a .serialized file").to_string();
    assert!(e.contains("t.xml:2:5") && e.contains("not the .serialized format"), "{e}");
}

/// Reconstruction filters: Mitsuba's names and defaults, errors at the filter's line.
#[test]
fn reconstruction_filters() {
    let film = |rfilter: &str| {
        format!(
            r#"<scene version="3.0.0"><sensor type="perspective"><film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/>{rfilter}</film></sensor></scene>"#
        )
    };
    let filter = |rfilter: &str| parse(&film(rfilter)).map(|s| s.hints.expect("hints").filter);
    use lucent_scene::PixelFilter as F;
    assert_eq!(filter("").expect("default"), F::Gaussian { stddev: 0.5 });
    assert_eq!(filter(r#"<rfilter type="mitchell"/>"#).expect("mitchell"), F::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 });
    assert_eq!(
        filter(r#"<rfilter type="mitchell"><float name="B" value="0.5"/><float name="C" value="0.25"/></rfilter>"#).expect("mitchell"),
        F::Mitchell { b: 0.5, c: 0.25 }
    );
    assert_eq!(filter(r#"<rfilter type="catmullrom"/>"#).expect("catmullrom"), F::Mitchell { b: 0.0, c: 0.5 });
    assert_eq!(filter(r#"<rfilter type="lanczos"/>"#).expect("lanczos"), F::Lanczos { lobes: 3.0 });
    assert_eq!(
        filter(r#"<rfilter type="lanczos"><integer name="lobes" value="2"/></rfilter>"#).expect("lanczos"),
        F::Lanczos { lobes: 2.0 }
    );
    let e = filter(r#"<rfilter type="lanczos"><integer name="lobes" value="0"/></rfilter>"#).expect_err("no lobes").to_string();
    assert!(e.contains("t.xml:1:") && e.contains("lobes"), "{e}");
    // The filters' profiles: Mitchell-Netravali's value at 0 is (6 − 2B)/6, Lanczos' zeros
    // fall on whole pixels.
    assert!((F::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 }.eval(0.0) - 8.0 / 9.0).abs() < 1e-6);
    assert!(
        F::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 }.eval(2.0).abs() < 1e-6 && F::Mitchell { b: 1.0 / 3.0, c: 1.0 / 3.0 }.eval(2.01) == 0.0
    );
    assert!(F::Lanczos { lobes: 3.0 }.eval(1.0).abs() < 1e-6 && F::Lanczos { lobes: 3.0 }.eval(1.5) < -0.1);
}

/// The `direct` integrator: one bounce (max_depth 2), its strategies from the sample counts.
#[test]
fn direct_integrator_strategies() {
    use lucent_scene::Strategies;
    let read = |e: i32, b: i32| {
        parse(&format!(
            r#"<scene version="3.0.0"><integrator type="direct"><integer name="emitter_samples" value="{e}"/><integer name="bsdf_samples" value="{b}"/></integrator></scene>"#
        ))
        .map(|s| s.hints.expect("hints"))
    };
    let h = read(1, 1).expect("both");
    assert_eq!((h.max_depth, h.strategies), (Some(2), Strategies::Both));
    assert_eq!(read(0, 1).expect("bsdf").strategies, Strategies::Bsdf);
    assert_eq!(read(4, 0).expect("emitters").strategies, Strategies::Emitters);
    assert_eq!(read(0, 0).expect("none").max_depth, Some(1), "no strategy: only what the camera sees");
    let e = read(-1, 1).expect_err("negative").to_string();
    assert!(e.contains("t.xml:1:") && e.contains("emitter_samples"), "{e}");
    let path = parse(r#"<scene version="3.0.0"><integrator type="path"/></scene>"#).expect("path").hints.expect("hints");
    assert_eq!(path.strategies, Strategies::Both);
}

/// Emitters' `sampling_weight`: a delta light of weight zero is dark in Mitsuba's path
/// tracer (only light sampling reaches it) and left out; other weights change no image.
#[test]
fn emitter_sampling_weights() {
    let s = parse(
        r#"<scene version="3.0.0">
        <emitter type="point"><float name="sampling_weight" value="0"/></emitter>
        <emitter type="spot"><float name="sampling_weight" value="2.5"/></emitter>
        <shape type="sphere"><emitter type="area"><float name="sampling_weight" value="0"/><rgb name="radiance" value="3"/></emitter></shape>
        </scene>"#,
    )
    .expect("scene");
    assert_eq!(s.lights.len(), 1, "the point light of weight 0 left out, the spot kept");
    assert!(matches!(s.lights[0].kind, LightKind::Spot { .. }));
    assert_eq!(s.materials.last().expect("material").emission, Vec3::splat(3.0), "an area light stays (BSDF rays meet it)");
    let e = err(r#"<scene version="3.0.0"><emitter type="point"><float name="sampling_weight" value="-1"/></emitter></scene>"#);
    assert!(e.contains("t.xml:1:") && e.contains("sampling_weight"), "{e}");
}

/// An area emitter defined at the top with an id, which shapes name with `<ref>` (as
/// Mitsuba's own Cornell box files do).
#[test]
fn area_emitters_by_reference() {
    let s = parse(
        r#"<scene version="3.0.0">
        <shape type="rectangle"><ref id="light"/></shape>
        <emitter type="area" id="light"><rgb name="radiance" value="4, 3, 2"/></emitter>
        </scene>"#,
    )
    .expect("scene");
    assert_eq!(s.materials.last().expect("material").emission, Vec3::new(4.0, 3.0, 2.0));
    // Without an id it still belongs inside a shape.
    let e = err(r#"<scene version="3.0.0"><emitter type="area"/></scene>"#);
    assert!(e.contains("belongs inside a <shape>"), "{e}");
}

#[test]
fn anisotropic_roughness() {
    let scene = |bsdf: &str| format!(r#"<scene version="3.0.0"><shape type="sphere">{bsdf}</shape></scene>"#);
    let s = parse(&scene(
        r#"<bsdf type="roughconductor"><string name="distribution" value="ggx"/>
            <float name="alpha_u" value="0.05"/><float name="alpha_v" value="0.3"/></bsdf>"#,
    ))
    .expect("anisotropic roughconductor");
    let r = s
        .materials
        .iter()
        .find_map(|m| match &m.bsdf {
            Some(Bsdf::Conductor { rough: Some(r), .. }) => Some(r.clone()),
            _ => None,
        })
        .expect("a rough conductor");
    assert_eq!((&r.alpha, &r.alpha_v), (&lucent_scene::FloatTex::Const(0.05), &Some(lucent_scene::FloatTex::Const(0.3))));
    assert!(s.materials.iter().any(|m| m.bsdf().anisotropic()));
    // Equal roughnesses are isotropic.
    let s = parse(&scene(r#"<bsdf type="roughdielectric"><float name="alpha_u" value="0.2"/><float name="alpha_v" value="0.2"/></bsdf>"#))
        .expect("roughdielectric");
    assert!(s.materials.iter().any(|m| matches!(&m.bsdf, Some(Bsdf::Dielectric { rough: Some(_), .. }))));
    assert!(!s.materials.iter().any(|m| m.bsdf().anisotropic()));
    // One without the other, as Mitsuba: an error at its line.
    let e = err(&scene("<bsdf type=\"roughconductor\">\n<float name=\"alpha_u\" value=\"0.05\"/></bsdf>"));
    assert!(e.starts_with("t.xml:2:") && e.contains("alpha_u and alpha_v"), "{e}");
}

/// Mitsuba's principled BSDF: its parameters and defaults, the lobes a file turns on (a
/// parameter set to the number 0 leaves its lobe off, as Mitsuba's flags), the index from
/// `specular`, and the error for both `eta` and `specular`.
#[test]
fn principled_bsdf() {
    let shape = |bsdf: &str| format!(r#"<scene version="3.0.0"><shape type="sphere">{bsdf}</shape></scene>"#);
    let s = parse(&shape(
        r#"<bsdf type="principled"><rgb name="base_color" value="0.2, 0.4, 0.6"/><float name="metallic" value="0.7"/>
           <float name="sheen" value="0"/><float name="spec_trans" value="0.3"/><float name="specular" value="0.6"/></bsdf>"#,
    ))
    .expect("principled");
    let Some(Bsdf::Principled(p)) = &s.materials.last().expect("a material").bsdf else { panic!("{:?}", s.materials) };
    assert_eq!(p.base_color, ColorTex::Const(Vec3::new(0.2, 0.4, 0.6)));
    assert_eq!((p.metallic.factor(), p.roughness.factor(), p.spec_trans.factor()), (0.7, 0.5, 0.3));
    assert!(p.has.metallic && p.has.spec_trans && !p.has.sheen && !p.has.clearcoat && !p.has.anisotropic);
    let want = 2.0 / (1.0 - (0.08f32 * 0.6).sqrt()) - 1.0;
    assert!((p.eta - want).abs() < 1e-6, "{} against {want}", p.eta);
    assert_eq!(p.rates, [1.0, 1.0, 1.0]);
    // Mitsuba's defaults: base colour 0.5, specular 0.5 (η = 1.5).
    let d = parse(&shape(r#"<bsdf type="principled"/>"#)).expect("defaults");
    let Some(Bsdf::Principled(p)) = &d.materials.last().expect("a material").bsdf else { panic!() };
    assert_eq!(p.base_color, ColorTex::Const(Vec3::splat(0.5)));
    assert!((p.eta - 1.5).abs() < 1e-6 && p.has == lucent_scene::PrincipledLobes::default());
    let e = err(&shape(r#"<bsdf type="principled"><float name="eta" value="1.4"/><float name="specular" value="0.5"/></bsdf>"#));
    assert!(e.contains("1:") && e.contains("'eta' or 'specular'"), "{e}");
}

/// The `aov` integrator's layers and the film's alpha: read in order with the wrapped
/// integrator's name; a type Mitsuba does not know is an error at its line; a film
/// `pixel_format` with alpha asks for an `A` channel.
#[test]
fn aov_integrator_and_pixel_format() {
    let s = parse(
        r#"<scene version="3.0.0"><integrator type="aov"><string name="aovs" value="d:depth, n:sh_normal,u:uv"/>
           <integrator type="path" name="img"><integer name="max_depth" value="3"/></integrator></integrator></scene>"#,
    )
    .expect("aov");
    let o = s.outputs.expect("outputs");
    assert_eq!(o.inner.as_deref(), Some("img"));
    assert!(!o.alpha);
    assert_eq!(o.aovs, [("d".into(), AovKind::Depth), ("n".into(), AovKind::ShNormal), ("u".into(), AovKind::Uv)]);
    assert_eq!(s.hints.expect("hints").max_depth, Some(3));
    let e = err(r#"<scene version="3.0.0">
        <integrator type="aov"><string name="aovs" value="d:deepness"/></integrator></scene>"#);
    assert!(e.contains("2:") && e.contains("deepness"), "{e}");
    let f = parse(&format!(
        r#"<scene version="3.0.0">{}</scene>"#,
        SENSOR.replace(r#"<rfilter type="box"/>"#, r#"<string name="pixel_format" value="rgba"/>"#)
    ))
    .expect("rgba");
    assert_eq!(f.outputs, Some(lucent_scene::Outputs { alpha: true, ..Default::default() }));
    assert!(parse(&format!(r#"<scene version="3.0.0">{SENSOR}</scene>"#)).expect("rgb").outputs.is_none());
}
