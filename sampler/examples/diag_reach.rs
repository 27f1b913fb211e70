use lightvol_sampler::scene_setup::{LightOverrides, SceneSource, load};
use lightvol_scene::bvh::Tracer;
use lightvol_volume::GridSpec;
fn main() {
    let src = SceneSource::File {
        path: "data/scenes/breakfast_room/BreakfastRoom.gltf".into(),
        options: Default::default(),
    };
    let l = load(&src, u128::MAX, &LightOverrides::default()).unwrap();
    let tr = Tracer::new(&l.scene);
    let g = GridSpec::new([-1.544, -2.016, 0.25], [1.710, 2.169, 2.75], [8, 10, 6]).unwrap();
    let mut cut = 0;
    for n in 0..480 {
        let (r, _) = lightvol_sampler::reach::node_reach(&tr, &g, n, None);
        if r.iter().any(|&v| v < 1.0) {
            cut += 1;
            println!("{:?} {:?}", g.node_coords(n), r);
        }
    }
    println!("cut {cut}");
}
