//! A morphing mesh placed by two nodes: each node's weights move its own copy only.

use base64::Engine as _;
use lucent_scene::{load, Geom};

/// One triangle with one morph target (vertex 0 moves by +1 along z), placed by two nodes;
/// an animation drives node 0's weight from 0 to 1 over one second, node 1 keeps weight 0.
fn two_nodes_one_morph() -> Vec<u8> {
    let mut bin = Vec::new();
    let f = |bin: &mut Vec<u8>, v: &[f32]| v.iter().for_each(|x| bin.extend_from_slice(&x.to_le_bytes()));
    f(&mut bin, &[0., 0., 0., 1., 0., 0., 0., 1., 0.]); // positions, 0..36
    f(&mut bin, &[0., 0., 1., 0., 0., 0., 0., 0., 0.]); // target displacements, 36..72
    f(&mut bin, &[0., 1.]); // key times, 72..80
    f(&mut bin, &[0., 1.]); // node 0's weights at those keys, 80..88
    let uri = format!("data:application/octet-stream;base64,{}", base64::engine::general_purpose::STANDARD.encode(&bin));
    format!(
        r#"{{"asset":{{"version":"2.0"}},
        "buffers":[{{"uri":"{uri}","byteLength":88}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":36}},{{"buffer":0,"byteOffset":36,"byteLength":36}},
                       {{"buffer":0,"byteOffset":72,"byteLength":8}},{{"buffer":0,"byteOffset":80,"byteLength":8}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[1,1,0]}},
                     {{"bufferView":1,"componentType":5126,"count":3,"type":"VEC3","min":[0,0,0],"max":[0,0,1]}},
                     {{"bufferView":2,"componentType":5126,"count":2,"type":"SCALAR","min":[0],"max":[1]}},
                     {{"bufferView":3,"componentType":5126,"count":2,"type":"SCALAR"}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"targets":[{{"POSITION":1}}]}}],"weights":[0]}}],
        "nodes":[{{"mesh":0}},{{"mesh":0,"translation":[5,0,0]}}],
        "animations":[{{"channels":[{{"sampler":0,"target":{{"node":0,"path":"weights"}}}}],
                        "samplers":[{{"input":2,"output":3,"interpolation":"LINEAR"}}]}}],
        "scenes":[{{"nodes":[0,1]}}],"scene":0}}"#
    )
    .into_bytes()
}

#[test]
fn a_morphing_mesh_placed_twice_deforms_per_node() {
    let d = tempfile::tempdir().expect("tmp");
    let p = d.path().join("two.gltf");
    std::fs::write(&p, two_nodes_one_morph()).expect("write");
    let scene = load(&p).expect("loads");
    assert_eq!(scene.instances.len(), 2);
    let mesh_of = |i: usize| match scene.instances[i].geom {
        Geom::Mesh(m) => m,
        Geom::Shape { .. } => panic!("instance {i} is not a mesh"),
    };
    assert_ne!(mesh_of(0), mesh_of(1), "each node deforms a mesh of its own");
    let anim = scene.animation.as_ref().expect("animated");
    let pose = anim.pose(1.0);
    let posed = |i: usize| {
        pose.meshes
            .iter()
            .find(|(m, _)| *m == mesh_of(i))
            .map(|(_, p)| p.clone())
            .unwrap_or_else(|| scene.meshes[mesh_of(i) as usize].positions.clone())
    };
    // Instances are listed in the loader's walk order: find each node's.
    let of_node = |n: u32| anim.instance_nodes.iter().position(|&k| k == n).expect("node placed");
    assert_eq!(posed(of_node(0))[0].z, 1.0, "node 0 is at full weight");
    assert_eq!(posed(of_node(1))[0].z, 0.0, "node 1 keeps weight 0");
}
