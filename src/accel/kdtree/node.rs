//! Compact 8-byte kD-tree node, laid out as pbrt-v3's `KdAccelNode`.
//!
//! Layout: word 0 is the split position (`f32` bits) of an inner node, or the offset of a leaf's
//! first entry in the tree's triangle-index list. Word 1 packs the low 2 bits as `0..=2` = split
//! axis of an inner node or `3` = leaf, and the upper 30 bits as the RIGHT child's node index
//! (inner) or the leaf's triangle count. The LEFT child of an inner node is always the next node
//! (`i + 1`): nodes are stored in depth-first pre-order.

use bytemuck::{Pod, Zeroable};

/// Largest child index or leaf triangle count that fits in the packed 30 bits.
pub(crate) const MAX_PACKED: u32 = (1 << 30) - 1;

/// One kD-tree node (8 bytes, `Pod`).
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
pub struct KdNode {
    /// Split position bits (inner) or first-entry offset (leaf).
    word: u32,
    /// `(child_or_count << 2) | axis_or_3`.
    flags: u32,
}

impl KdNode {
    /// Inner node splitting `axis` at `split`; `right` is the right child's index (the left
    /// child is the next node).
    #[inline]
    pub fn inner(axis: usize, split: f32, right: u32) -> KdNode {
        debug_assert!(axis < 3 && right <= MAX_PACKED);
        KdNode {
            word: split.to_bits(),
            flags: (right << 2) | axis as u32,
        }
    }

    /// Leaf listing `count` entries starting at `offset` in the triangle-index list.
    #[inline]
    pub fn leaf(offset: u32, count: u32) -> KdNode {
        debug_assert!(count <= MAX_PACKED);
        KdNode {
            word: offset,
            flags: (count << 2) | 3,
        }
    }

    /// True for a leaf.
    #[inline(always)]
    pub fn is_leaf(self) -> bool {
        self.flags & 3 == 3
    }

    /// Split axis (inner nodes only).
    #[inline(always)]
    pub fn axis(self) -> usize {
        (self.flags & 3) as usize
    }

    /// Split position (inner nodes only).
    #[inline(always)]
    pub fn split(self) -> f32 {
        f32::from_bits(self.word)
    }

    /// Right child's node index (inner nodes only).
    #[inline(always)]
    pub fn right(self) -> u32 {
        self.flags >> 2
    }

    /// First entry of the leaf in the triangle-index list (leaves only).
    #[inline(always)]
    pub fn offset(self) -> u32 {
        self.word
    }

    /// Number of triangles in the leaf (leaves only).
    #[inline(always)]
    pub fn count(self) -> u32 {
        self.flags >> 2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_is_eight_bytes_and_round_trips_fields() {
        assert_eq!(std::mem::size_of::<KdNode>(), 8);
        let n = KdNode::inner(2, -10.070_55, 12345);
        assert!(!n.is_leaf());
        assert_eq!((n.axis(), n.split(), n.right()), (2, -10.070_55, 12345));
        let l = KdNode::leaf(77, MAX_PACKED);
        assert!(l.is_leaf());
        assert_eq!((l.offset(), l.count()), (77, MAX_PACKED));
        let z = KdNode::inner(0, -0.0, 1);
        assert_eq!(z.split().to_bits(), (-0.0f32).to_bits());
    }
}
