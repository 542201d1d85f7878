//! Moving a tree from one render frame to another: the root box and every split plane go through
//! world coordinates in f64, exactly as a tree file's numbers do ([`KdTree::read_text_in`]), so a
//! tree built once serves every camera of a camera path.

use rayon::prelude::*;

use super::{KdNode, KdTree};
use crate::geometry::frame::RenderFrame;

impl KdTree {
    /// This tree (built or read in frame `from`) in frame `to`. Triangle lists are unchanged;
    /// wrap it in a [`super::KdAccel`] with the mesh in the new frame to trace it.
    pub fn reframed(&self, from: &RenderFrame, to: &RenderFrame) -> KdTree {
        self.clone().into_reframed(from, to)
    }

    /// [`KdTree::reframed`] in place (no copy of the node or triangle arrays; the nodes are moved
    /// in parallel). Into its own frame a tree stays as it is (through world coordinates and back
    /// a coordinate could round).
    pub(crate) fn into_reframed(mut self, from: &RenderFrame, to: &RenderFrame) -> KdTree {
        if from == to {
            return self;
        }
        let move_to = |axis: usize, x: f32| to.coordinate(axis, from.world_coordinate(axis, x));
        self.nodes
            .par_iter_mut()
            .with_min_len(1 << 14)
            .for_each(|n| {
                if !n.is_leaf() {
                    *n = KdNode::inner(n.axis(), move_to(n.axis(), n.split()), n.right());
                }
            });
        let (lo, hi) = self.root;
        self.root = (
            std::array::from_fn(|k| move_to(k, lo[k])),
            std::array::from_fn(|k| move_to(k, hi[k])),
        );
        self
    }
}
