//! The image does not depend on how the kD tree was made or how many threads trace it: midpoint,
//! SAH and a tree file written and read back give byte-identical Sibenik renders; and the builders
//! give the same tree on any number of threads, on meshes large enough to build in parallel.

use wavefront::accel::kdtree::{BuildMethod, KdTree};
use wavefront::mesh::TriangleMesh;
use wavefront::scene::TreeSource;
use wavefront::scene::builtin::sibenik;

/// `sibenik-shadows` through a 128 × 128 window around the image centre (the midpoint tree's
/// huge leaves make full frames slow), with the given tree.
fn render_with(tree: TreeSource, threads: usize, mesh: &std::path::Path) -> Vec<u8> {
    let mut scene = sibenik(true);
    scene.meshes[0].path = mesh.to_path_buf(); // resolved by the test kit
    scene.meshes[0].kdtree = tree;
    wavefront_kit::testkit::sibenik_crop(&mut scene, 128);
    wavefront_kit::testkit::in_pool(threads, || wavefront_kit::testkit::render_png_bytes(&scene))
}

#[test]
fn midpoint_sah_and_tree_file_render_identically_on_any_thread_count() {
    let Some(mesh_path) = wavefront_kit::testkit::sibenik_mesh() else {
        return;
    };
    let mesh = TriangleMesh::load_obj(&mesh_path).unwrap();
    let file = std::env::temp_dir().join(format!("wavefront-builders-{}.kd", std::process::id()));
    let mut text = Vec::new();
    KdTree::build(&mesh, BuildMethod::Sah)
        .write_text(&mut text)
        .unwrap();
    std::fs::write(&file, text).unwrap();

    let reference = render_with(TreeSource::Sah, 2, &mesh_path);
    let lit = reference.chunks(3).filter(|p| p[0] > 0).count();
    let dark = reference.chunks(3).filter(|p| p[0] == 0).count();
    assert!(
        lit > 1000 && dark > 100,
        "the window must show lit and shadowed surfaces ({lit}, {dark})"
    );
    for (tree, threads) in [
        (TreeSource::Sah, 1),
        (TreeSource::Midpoint, 1),
        (TreeSource::Midpoint, 2),
        (TreeSource::File(file.clone()), 1),
        (TreeSource::File(file.clone()), 2),
    ] {
        let image = render_with(tree.clone(), threads, &mesh_path);
        assert!(
            image == reference,
            "{tree:?} on {threads} thread(s) differs from SAH on 2"
        );
    }
    let _ = std::fs::remove_file(&file);
}

/// A seeded soup of `n` small triangles in a 100-unit cube: large enough that the builders' upper
/// levels take the parallel path (the SAH builder forks above 4,096 triangles per node).
fn soup(n: usize) -> TriangleMesh {
    let mut rng = wavefront::sampling::Rng(0x50_0b);
    let mut v = Vec::with_capacity(3 * n);
    for _ in 0..n {
        let c = [0; 3].map(|_| rng.range(0.0, 100.0));
        for _ in 0..3 {
            v.push([0, 1, 2].map(|k| c[k] + rng.range(-1.0, 1.0)));
        }
    }
    let idx = (0..n as u32)
        .map(|t| [3 * t, 3 * t + 1, 3 * t + 2])
        .collect();
    TriangleMesh::new(v, idx)
}

#[test]
fn large_meshes_build_the_same_tree_on_1_2_and_4_threads() {
    let mesh = soup(40_000);
    for method in [BuildMethod::Sah, BuildMethod::Midpoint] {
        let one = wavefront_kit::testkit::in_pool(1, || KdTree::build(&mesh, method));
        one.validate(&mesh).expect("valid tree");
        assert!(one.nodes().len() > 1000, "{method:?}: a deep tree");
        for threads in [2, 4] {
            let many = wavefront_kit::testkit::in_pool(threads, || KdTree::build(&mesh, method));
            assert!(one == many, "{method:?} tree differs on {threads} threads");
        }
    }
}

#[test]
fn binned_upper_levels_cost_within_five_percent_of_the_exact_sweep() {
    let mut meshes = vec![("soup", soup(40_000))];
    if let Some(path) = wavefront_kit::testkit::sibenik_mesh() {
        meshes.push(("sibenik", TriangleMesh::load_obj(&path).unwrap()));
    }
    for (name, mesh) in meshes {
        let binned = KdTree::build(&mesh, BuildMethod::Sah);
        let exact = KdTree::build_sah_exact(&mesh);
        binned.validate(&mesh).expect("valid binned tree");
        assert!(binned != exact, "{name}: the binned path was not taken");
        let (b, e) = (binned.stats(&mesh).sah_cost, exact.stats(&mesh).sah_cost);
        assert!(b <= 1.05 * e, "{name}: binned SAH cost {b} vs exact {e}");
    }
}
