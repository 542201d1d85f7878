//! [`Region`]: the rectangle of the image a render covers (SPEC §11) — `--pixel-bounds`,
//! `--tile K/N` — and the map from its pixels to the whole image's.
//!
//! A region's pixels are numbered row-major from its top-left corner ("local" indices: the film of
//! a region render has the region's size); sample seeds and camera rays use the whole image's
//! pixel index, so a region renders exactly the full image's pixels there.

use std::fmt;
use std::str::FromStr;

use crate::queue::PixelIndex;

/// A rectangle of pixels: columns `x0 ≤ i < x1`, rows `y0 ≤ j < y1`, row 0 at the top.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    /// First column.
    pub x0: u32,
    /// One past the last column.
    pub x1: u32,
    /// First row (0 is the top).
    pub y0: u32,
    /// One past the last row.
    pub y1: u32,
}

/// A region or tile specification that does not fit the image or cannot be parsed.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("invalid {key} {value:?}: {message}")]
pub struct RegionError {
    /// The setting, e.g. `--tile`.
    pub key: &'static str,
    /// The value given.
    pub value: String,
    /// What is wrong.
    pub message: String,
}

impl Region {
    /// The whole `width × height` image.
    pub fn full(width: u32, height: u32) -> Region {
        Region {
            x0: 0,
            x1: width,
            y0: 0,
            y1: height,
        }
    }

    /// Columns in the region.
    pub fn width(&self) -> u32 {
        self.x1.saturating_sub(self.x0)
    }

    /// Rows in the region.
    pub fn height(&self) -> u32 {
        self.y1.saturating_sub(self.y0)
    }

    /// Pixels in the region.
    pub fn pixels(&self) -> u64 {
        u64::from(self.width()) * u64::from(self.height())
    }

    /// True when the region holds no pixel.
    pub fn is_empty(&self) -> bool {
        self.width() == 0 || self.height() == 0
    }

    /// True when the region is the whole `width × height` image.
    pub fn is_full(&self, width: u32, height: u32) -> bool {
        *self == Region::full(width, height)
    }

    /// The part of the region inside the `width × height` image (possibly empty).
    pub(crate) fn clipped(&self, width: u32, height: u32) -> Region {
        let x1 = self.x1.min(width);
        let y1 = self.y1.min(height);
        Region {
            x0: self.x0.min(x1),
            x1,
            y0: self.y0.min(y1),
            y1,
        }
    }

    /// The overlap of two regions, if they share a pixel.
    pub fn intersection(&self, other: &Region) -> Option<Region> {
        let r = Region {
            x0: self.x0.max(other.x0),
            x1: self.x1.min(other.x1),
            y0: self.y0.max(other.y0),
            y1: self.y1.min(other.y1),
        };
        (r.x0 < r.x1 && r.y0 < r.y1).then_some(r)
    }

    /// Tile `k` of `n` of a `height`-row image: rows `⌊k·H/n⌋ ≤ j < ⌊(k+1)·H/n⌋`, every column.
    /// Needs `0 ≤ k < n ≤ H`, so every tile has at least one row.
    pub fn tile(k: u32, n: u32, width: u32, height: u32) -> Result<Region, RegionError> {
        let bad = |message: String| RegionError {
            key: "--tile",
            value: format!("{k}/{n}"),
            message,
        };
        if n == 0 {
            return Err(bad("the number of tiles must be at least 1".into()));
        }
        if n > height {
            return Err(bad(format!(
                "{n} tiles of a {height}-row image: at most one tile per row"
            )));
        }
        if k >= n {
            return Err(bad(format!("tile index {k} must be below {n} (0 ≤ K < N)")));
        }
        let row = |k: u32| (u64::from(k) * u64::from(height) / u64::from(n)) as u32;
        Ok(Region {
            x0: 0,
            x1: width,
            y0: row(k),
            y1: row(k + 1),
        })
    }

    /// Checks that the region is non-empty and inside a `width × height` image (`key` names the
    /// setting in the error).
    pub fn check_inside(
        &self,
        width: u32,
        height: u32,
        key: &'static str,
    ) -> Result<(), RegionError> {
        let bad = |message: String| RegionError {
            key,
            value: self.to_string(),
            message,
        };
        if self.x0 >= self.x1 || self.y0 >= self.y1 {
            return Err(bad(
                "needs x0 < x1 and y0 < y1 (end-exclusive bounds)".into()
            ));
        }
        if self.x1 > width || self.y1 > height {
            return Err(bad(format!(
                "outside the {width}x{height} image (needs x1 ≤ {width}, y1 ≤ {height})"
            )));
        }
        Ok(())
    }

    /// The whole image's pixel index of the region's `local`-th pixel (row-major within the
    /// region) in an image `image_width` pixels wide.
    #[inline]
    pub fn pixel(&self, local: u32, image_width: u32) -> PixelIndex {
        let w = self.width();
        if w == image_width {
            // Full-width bands (tiles, the whole image): one contiguous run of the image.
            PixelIndex(self.y0 * image_width + local)
        } else {
            PixelIndex((self.y0 + local / w) * image_width + self.x0 + local % w)
        }
    }
}

/// `x0,x1,y0,y1`, the format of `--pixel-bounds` and of the `wavefront:bounds` tile chunk.
impl fmt::Display for Region {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{},{},{},{}", self.x0, self.x1, self.y0, self.y1)
    }
}

/// Parses `x0,x1,y0,y1` (four non-negative integers). Range checks against an image are
/// [`Region::check_inside`]'s.
impl FromStr for Region {
    type Err = RegionError;

    fn from_str(s: &str) -> Result<Region, RegionError> {
        let bad = |message: &str| RegionError {
            key: "--pixel-bounds",
            value: s.to_owned(),
            message: message.to_owned(),
        };
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let [x0, x1, y0, y1] = parts.as_slice() else {
            return Err(bad("expected four integers x0,x1,y0,y1"));
        };
        let n = |t: &str| {
            t.parse::<u32>()
                .map_err(|_| bad("expected four non-negative integers x0,x1,y0,y1"))
        };
        Ok(Region {
            x0: n(x0)?,
            x1: n(x1)?,
            y0: n(y0)?,
            y1: n(y1)?,
        })
    }
}

/// A `--tile` value: `K/N`, or `N` with `K` taken from the environment of a job array task.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum TileSpec {
    /// `K/N`.
    Index {
        /// The tile, `0 ≤ k < n`.
        k: u32,
        /// The number of tiles.
        n: u32,
    },
    /// `N`: the tile index comes from `TILE_INDEX_VARIABLES`.
    FromEnvironment {
        /// The number of tiles.
        n: u32,
    },
}

/// Where `--tile N` finds its tile index, in order: a Slurm job array task, then a Kubernetes
/// Indexed Job's pod.
pub(crate) const TILE_INDEX_VARIABLES: [&str; 2] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX"];

impl FromStr for TileSpec {
    type Err = RegionError;

    fn from_str(s: &str) -> Result<TileSpec, RegionError> {
        let bad = |message: &str| RegionError {
            key: "--tile",
            value: s.to_owned(),
            message: message.to_owned(),
        };
        let number = |t: &str| {
            t.trim()
                .parse::<u32>()
                .map_err(|_| bad("expected K/N or N (non-negative integers)"))
        };
        match s.split_once('/') {
            Some((k, n)) => Ok(TileSpec::Index {
                k: number(k)?,
                n: number(n)?,
            }),
            None => Ok(TileSpec::FromEnvironment { n: number(s)? }),
        }
    }
}

impl TileSpec {
    /// The tile's region of a `width × height` image; `var` looks up environment variables
    /// (`std::env::var(..).ok()` in the CLI) for the `N` form.
    pub fn region(
        &self,
        width: u32,
        height: u32,
        var: impl Fn(&str) -> Option<String>,
    ) -> Result<Region, RegionError> {
        match *self {
            TileSpec::Index { k, n } => Region::tile(k, n, width, height),
            TileSpec::FromEnvironment { n } => {
                let found = TILE_INDEX_VARIABLES
                    .iter()
                    .find_map(|name| var(name).map(|v| (*name, v)));
                let Some((name, value)) = found else {
                    return Err(RegionError {
                        key: "--tile",
                        value: n.to_string(),
                        message: format!(
                            "no tile index: give --tile K/{n}, or run as a job array task \
                             (neither {} nor {} is set)",
                            TILE_INDEX_VARIABLES[0], TILE_INDEX_VARIABLES[1]
                        ),
                    });
                };
                let k = value.trim().parse::<u32>().map_err(|_| RegionError {
                    key: "--tile",
                    value: n.to_string(),
                    message: format!("{name}={value:?} is not a tile index"),
                })?;
                Region::tile(k, n, width, height)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiles_cover_every_row_once_in_order() {
        for (h, n) in [(512, 3), (7, 7), (10, 4), (1, 1)] {
            let tiles: Vec<Region> = (0..n).map(|k| Region::tile(k, n, 5, h).unwrap()).collect();
            assert_eq!(tiles[0].y0, 0);
            assert_eq!(tiles[n as usize - 1].y1, h);
            for w in tiles.windows(2) {
                assert_eq!(w[0].y1, w[1].y0);
            }
            assert!(tiles.iter().all(|t| t.height() >= 1 && t.width() == 5));
        }
        // ⌊K·H/N⌋: 512 rows in 3 tiles are 170, 171, 171.
        let t = Region::tile(1, 3, 512, 512).unwrap();
        assert_eq!((t.y0, t.y1), (170, 341));
    }

    #[test]
    fn impossible_tiles_are_rejected() {
        let e = Region::tile(5, 4, 8, 8).unwrap_err().to_string();
        assert!(e.contains("--tile \"5/4\"") && e.contains("below 4"), "{e}");
        assert!(Region::tile(0, 0, 8, 8).is_err());
        assert!(
            Region::tile(0, 9, 8, 8)
                .unwrap_err()
                .message
                .contains("one tile per row")
        );
    }

    #[test]
    fn bounds_parse_and_check_against_the_image() {
        let r: Region = "10,20,5,6".parse().unwrap();
        assert_eq!(
            r,
            Region {
                x0: 10,
                x1: 20,
                y0: 5,
                y1: 6
            }
        );
        assert_eq!(r.to_string(), "10,20,5,6");
        assert!(r.check_inside(20, 6, "--pixel-bounds").is_ok());
        assert!(r.check_inside(19, 6, "--pixel-bounds").is_err());
        let empty: Region = "3,3,0,1".parse().unwrap();
        assert!(empty.check_inside(8, 8, "--pixel-bounds").is_err());
        for bad in ["1,2,3", "1,2,3,4,5", "a,2,3,4", "-1,2,3,4", ""] {
            assert!(bad.parse::<Region>().is_err(), "{bad}");
        }
    }

    #[test]
    fn local_pixels_map_to_the_whole_images_indices() {
        let r: Region = "2,5,1,3".parse().unwrap();
        let pixels: Vec<u32> = (0..6).map(|l| r.pixel(l, 10).0).collect();
        assert_eq!(pixels, [12, 13, 14, 22, 23, 24]);
        let band = Region::tile(1, 2, 10, 4).unwrap();
        assert_eq!(band.pixel(0, 10), PixelIndex(20));
        assert_eq!(band.pixel(13, 10), PixelIndex(33));
    }

    #[test]
    fn tile_n_takes_its_index_from_slurm_then_kubernetes() {
        let spec: TileSpec = "4".parse().unwrap();
        assert_eq!(spec, TileSpec::FromEnvironment { n: 4 });
        let slurm = |v: &str| (v == "SLURM_ARRAY_TASK_ID").then(|| "2".to_owned());
        assert_eq!(
            spec.region(8, 8, slurm).unwrap(),
            Region::tile(2, 4, 8, 8).unwrap()
        );
        let both = |v: &str| match v {
            "SLURM_ARRAY_TASK_ID" => Some("1".to_owned()),
            "JOB_COMPLETION_INDEX" => Some("3".to_owned()),
            _ => None,
        };
        assert_eq!(spec.region(8, 8, both).unwrap().y0, 2);
        let k8s = |v: &str| (v == "JOB_COMPLETION_INDEX").then(|| "3".to_owned());
        assert_eq!(spec.region(8, 8, k8s).unwrap().y0, 6);
        let e = spec.region(8, 8, |_| None).unwrap_err().to_string();
        assert!(
            e.contains("SLURM_ARRAY_TASK_ID") && e.contains("JOB_COMPLETION_INDEX"),
            "{e}"
        );
        let e = spec
            .region(8, 8, |_| Some("x".into()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("not a tile index"), "{e}");
        let e = spec
            .region(8, 8, |_| Some("4".into()))
            .unwrap_err()
            .to_string();
        assert!(e.contains("below 4"), "{e}");
        assert_eq!(
            "1/3".parse::<TileSpec>().unwrap(),
            TileSpec::Index { k: 1, n: 3 }
        );
        assert!("1/".parse::<TileSpec>().is_err());
    }
}
