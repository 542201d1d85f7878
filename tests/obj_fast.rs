//! The fast OBJ reader against tobj on the OBJ files the tests read: identical positions and
//! triangles (the mutated files of `tests/bad_input.rs` and the generated ones of the unit tests
//! are checked where they are made).

use wavefront::mesh::ObjMesh;

#[test]
fn sibenik_reads_the_same_through_the_fast_path_and_tobj() {
    let Some(path) = wavefront_kit::testkit::sibenik_mesh() else {
        return;
    };
    let bytes = std::fs::read(&path).unwrap();
    let (positions, indices) = wavefront::mesh::obj_fast::parse(&bytes).expect("fast path taken");
    let slow = ObjMesh::read(&path).unwrap();
    assert_eq!(indices.len(), 75_284);
    assert!(positions == slow.positions, "positions differ");
    assert!(indices == slow.indices, "triangles differ");
    // And on any thread count.
    let one = wavefront_kit::testkit::in_pool(1, || wavefront::mesh::obj_fast::parse(&bytes));
    assert!(one == Some((positions, indices)));
}
