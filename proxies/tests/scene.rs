//! Scene files: the default scene round-trips through JSON; bad input is an error.

use lightvol_proxies::error::ProxyError;
use lightvol_proxies::receiver_scene::{ReceiverBuffer, Scene};

#[test]
fn default_scene_round_trips_through_json() {
    let s = Scene::default_scene();
    let text = serde_json::to_string(&s).unwrap();
    assert_eq!(Scene::from_json(&text).unwrap(), s);
    // The camera sees receivers on the floor and both walls.
    let b = ReceiverBuffer::render(&s, 64, 48);
    let normals: std::collections::BTreeSet<[i32; 3]> =
        (0..b.depth.len()).filter(|&i| b.valid(i)).map(|i| b.normal[i].map(|v| v.round() as i32)).collect();
    assert_eq!(normals.len(), 3, "{normals:?}");
}

#[test]
fn bad_scenes_are_errors() {
    assert!(matches!(Scene::from_json("{"), Err(ProxyError::Scene(_))));
    let mut s = Scene::default_scene();
    s.proxies[0].radius = -1.0;
    let text = serde_json::to_string(&s).unwrap();
    assert!(matches!(Scene::from_json(&text), Err(ProxyError::Scene(m)) if m.contains("proxy 0")));
    let mut s = Scene::default_scene();
    s.light.sun_dir = [1.0, 1.0, 0.0];
    assert!(Scene::from_json(&serde_json::to_string(&s).unwrap()).is_err());
}
