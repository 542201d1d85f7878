//! Many spheres (issue 26): a world of thousands of spheres traces them through a BVH and renders
//! exactly the image of testing every sphere one by one, on any number of threads; stage elision
//! (SPEC §7) is unchanged by it.

use wavefront::scene::builtin::many_spheres;
use wavefront::{Pipeline, RenderOptions, Scene, Stage, World};
use wavefront_kit::testkit::*;

/// `many_spheres(n)` at `size²` with 2 samples per pixel (jittered rays: the rays are not all
/// through pixel centres) and 3 reflections.
fn scene(n: usize, size: u32) -> Scene {
    let mut s = many_spheres(n);
    (s.image.width, s.image.height, s.image.samples) = (size, size, 2);
    s.render.max_depth = 3;
    s
}

fn png(scene: &Scene, world: &World) -> Vec<u8> {
    wavefront::render(scene, world, RenderOptions::default(), |_, _| {})
        .0
        .to_rgb8(scene.image.gamma)
}

#[test]
fn the_bvh_renders_the_image_of_the_direct_loop() {
    let scene = scene(20_000, 96);
    let world = World::load(&scene).unwrap();
    assert!(world.sphere_bvh().is_some());
    let direct = World::load(&scene).unwrap().with_direct_spheres();
    assert!(direct.sphere_bvh().is_none());
    let (a, b) = (png(&scene, &world), png(&scene, &direct));
    let first = a.iter().zip(&b).position(|(x, y)| x != y);
    assert_eq!(first.map(|i| i / 3), None, "first differing pixel");
    // Not a blank frame: spheres of all three colours and the floor.
    let mut colours: Vec<&[u8]> = a.chunks(3).collect();
    colours.sort();
    colours.dedup();
    assert!(colours.len() > 1000, "{} colours", colours.len());
}

#[test]
fn many_spheres_render_identically_on_1_2_and_4_threads() {
    let scene = scene(50_000, 64);
    let one = in_pool(1, || render_png_bytes(&scene));
    for threads in [2, 4] {
        let many = in_pool(threads, || render_png_bytes(&scene));
        assert!(one == many, "{threads} threads differ from 1");
    }
}

#[test]
fn stage_elision_holds_for_many_spheres() {
    use Stage::*;
    let many = many_spheres(1000);
    let p = Pipeline::for_scene(&many);
    assert_eq!(
        p.depths
            .iter()
            .map(|d| d.stages.clone())
            .collect::<Vec<_>>(),
        vec![
            vec![Generate, Intersect, Shade, Shadow, Reflect],
            vec![Intersect, Shade, Shadow, Reflect],
            vec![Intersect, Shade, Shadow],
        ]
    );
    assert!(
        p.geometry.contains("1000 spheres in a BVH"),
        "{}",
        p.geometry
    );
    // No mirror, no light: no reflect stage, no shadow stage, one depth.
    let mut plain = many.clone();
    plain.materials.iter_mut().for_each(|m| m.alpha = 0.0);
    plain.lights.clear();
    let p = Pipeline::for_scene(&plain);
    assert_eq!(p.depths.len(), 1);
    assert!(!p.runs(Reflect) && !p.runs(Shadow), "{p}");
    // Up to SPHERE_BVH_MIN spheres are tested directly (scene A's path).
    let few = many_spheres(wavefront::world::SPHERE_BVH_MIN);
    assert!(World::load(&few).unwrap().sphere_bvh().is_none());
    let p = Pipeline::for_scene(&few);
    assert!(
        p.geometry
            .starts_with("128 spheres, 1 planes (brute force)"),
        "{}",
        p.geometry
    );
}
