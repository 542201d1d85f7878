//! Writes the built-in `many-spheres` scene (scene A with seeded random spheres, 256 × 256) as a
//! scene file, optionally with another sphere count: the input of the many-primitives timing
//! through the whole command, parse included. The file belongs in /tmp, never in the repository.
//!
//!     cargo run --release -p wavefront-kit --example many_spheres -- [SPHERES] > /tmp/many.toml
//!     wavefront render /tmp/many.toml --threads 2 -o /tmp/many.png
//!
//! With the default 100,000 spheres the file renders byte-identically to
//! `wavefront render many-spheres`.

fn main() -> anyhow::Result<()> {
    let n = match std::env::args().nth(1) {
        Some(a) => a
            .parse()
            .map_err(|_| anyhow::anyhow!("usage: many_spheres [SPHERES]"))?,
        None => wavefront::scene::builtin::MANY_SPHERES,
    };
    let scene = wavefront::scene::builtin::many_spheres(n);
    let text = wavefront_kit::scene_toml::analytic_scene_toml(&scene)
        .ok_or_else(|| anyhow::anyhow!("many-spheres is not an analytic scene"))?;
    print!(
        "# Written by tools/kit/examples/many_spheres.rs: the built-in many-spheres with {n} spheres.\n\n{text}"
    );
    Ok(())
}
