//! [`Wave`]: the pixels rendered together, and the map between their sample slots and pixels.
//!
//! Every queue row carries a [`SampleSlot`]; a wave says which pixel and which of its samples a
//! slot is. This is the one place where slots (queue side) and pixels (film side) meet.

use crate::queue::{PixelIndex, SampleSlot};

/// A contiguous range of pixels rendered together; its samples fill slots `0..len()`, pixel by
/// pixel (sample `s` of the wave's `k`-th pixel has slot `k · samples + s`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wave {
    /// First pixel (row-major index into the image).
    pub first_pixel: PixelIndex,
    /// Number of pixels.
    pub pixels: u32,
    /// Samples per pixel.
    pub samples: u32,
}

impl Wave {
    /// Number of samples (= primary rays) in the wave.
    pub fn len(&self) -> usize {
        self.pixels as usize * self.samples as usize
    }

    /// True when the wave holds no pixels.
    pub fn is_empty(&self) -> bool {
        self.pixels == 0
    }

    /// The pixel a slot belongs to and the slot's sample number within that pixel.
    #[inline]
    pub fn pixel_of(&self, slot: SampleSlot) -> (PixelIndex, u32) {
        (
            PixelIndex(self.first_pixel.0 + slot.0 / self.samples),
            slot.0 % self.samples,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_map_to_pixels_sample_by_sample() {
        let w = Wave {
            first_pixel: PixelIndex(10),
            pixels: 3,
            samples: 4,
        };
        assert_eq!(w.len(), 12);
        assert_eq!(w.pixel_of(SampleSlot(0)), (PixelIndex(10), 0));
        assert_eq!(w.pixel_of(SampleSlot(7)), (PixelIndex(11), 3));
        assert_eq!(w.pixel_of(SampleSlot(11)), (PixelIndex(12), 3));
    }
}
