//! [`Wave`]: the pixels rendered together, and the map between their sample slots and pixels.
//!
//! Every queue row carries a [`SampleSlot`]; a wave says which pixel and which of its samples a
//! slot is. This is the one place where slots (queue side) and pixels (film side) meet.

use crate::queue::region::Region;
use crate::queue::{PixelIndex, SampleSlot};

/// A contiguous run of a region's pixels (row-major within the region) rendered together; its
/// samples fill slots `0..len()`, pixel by pixel (sample `s` of the wave's `k`-th pixel has slot
/// `k · samples + s`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Wave {
    /// The rectangle being rendered (the whole image for a full render); the film has its size.
    pub region: Region,
    /// Width of the whole image: pixel indices (and so sample seeds) are the whole image's.
    pub image_width: u32,
    /// First pixel, as a row-major index into the region (and so into the region's film).
    pub first: u32,
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

    /// A wave of `pixels` pixels of the whole `image_width`-wide image starting at row-major
    /// pixel `first`.
    pub fn of_image(
        image_width: u32,
        image_height: u32,
        first: u32,
        pixels: u32,
        samples: u32,
    ) -> Wave {
        Wave {
            region: Region::full(image_width, image_height),
            image_width,
            first,
            pixels,
            samples,
        }
    }

    /// The pixel (of the whole image) a slot belongs to and the slot's sample number within that
    /// pixel.
    #[inline]
    pub(crate) fn pixel_of(&self, slot: SampleSlot) -> (PixelIndex, u32) {
        let local = self.first + slot.0 / self.samples;
        (
            self.region.pixel(local, self.image_width),
            slot.0 % self.samples,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn slots_map_to_pixels_sample_by_sample() {
        let w = Wave::of_image(100, 100, 10, 3, 4);
        assert_eq!(w.len(), 12);
        assert_eq!(w.pixel_of(SampleSlot(0)), (PixelIndex(10), 0));
        assert_eq!(w.pixel_of(SampleSlot(7)), (PixelIndex(11), 3));
        assert_eq!(w.pixel_of(SampleSlot(11)), (PixelIndex(12), 3));
    }

    #[test]
    fn a_rectangles_slots_map_to_the_whole_images_pixels() {
        // Columns 2..4 of rows 1..3 of a 10-wide image; the wave starts at its 2nd pixel.
        let w = Wave {
            region: "2,4,1,3".parse().unwrap(),
            image_width: 10,
            first: 1,
            pixels: 3,
            samples: 2,
        };
        assert_eq!(w.pixel_of(SampleSlot(0)), (PixelIndex(13), 0));
        assert_eq!(w.pixel_of(SampleSlot(3)), (PixelIndex(22), 1));
        assert_eq!(w.pixel_of(SampleSlot(5)), (PixelIndex(23), 1));
    }
}
