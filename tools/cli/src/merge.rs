//! `wavefront merge TILE... -o OUT`: reads every tile, checks they make one image (one
//! fingerprint and image size, every pixel exactly once), then writes OUT atomically. On any error
//! nothing is written and the error names the tile (or the uncovered pixels).

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

use crate::tile::{merge_tiles, read_tile};

/// Arguments of `merge`.
#[derive(Args, Debug)]
pub struct MergeArgs {
    /// Tiles written by `render --tile` or `render --pixel-bounds` (PNG, or EXR for linear HDR).
    #[arg(required = true)]
    pub tiles: Vec<PathBuf>,
    /// The merged image (.png or .ppm from PNG tiles, .exr from EXR tiles).
    #[arg(short, long)]
    pub output: PathBuf,
}

/// Runs `merge`.
pub fn run(args: &MergeArgs) -> Result<()> {
    let tiles = args
        .tiles
        .iter()
        .map(|t| read_tile(t))
        .collect::<Result<Vec<_>, _>>()?;
    let merged = merge_tiles(&tiles)?;
    Ok(merged.save(&args.output)?)
}
