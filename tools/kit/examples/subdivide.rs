//! Makes a large test mesh from a small one: every triangle split into four at its edge midpoints
//! (shared edges share their midpoint), `LEVELS` times, written as `v`/`f` OBJ lines. Used for the
//! README's million-triangle figures; the output belongs in /tmp, never in the repository.
//!
//!     cargo run --release -p wavefront-kit --example subdivide -- SIBENIK.obj 2 /tmp/sibenik16.obj

use std::collections::HashMap;
use std::io::Write;

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let [_, input, levels, output] = args.as_slice() else {
        anyhow::bail!("usage: subdivide MESH.obj LEVELS OUT.obj");
    };
    let levels: u32 = levels.parse()?;
    let mesh = wavefront::mesh::ObjMesh::read(std::path::Path::new(input))?;
    let (mut v, mut f) = (mesh.positions, mesh.indices);
    for _ in 0..levels {
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut next = Vec::with_capacity(4 * f.len());
        for t in &f {
            let mut m = [0u32; 3];
            for k in 0..3 {
                let (a, b) = (t[k], t[(k + 1) % 3]);
                m[k] = *mid.entry((a.min(b), a.max(b))).or_insert_with(|| {
                    let (p, q) = (v[a as usize], v[b as usize]);
                    v.push([0, 1, 2].map(|i| 0.5 * (p[i] + q[i])));
                    (v.len() - 1) as u32
                });
            }
            next.extend([
                [t[0], m[0], m[2]],
                [m[0], t[1], m[1]],
                [m[2], m[1], t[2]],
                [m[0], m[1], m[2]],
            ]);
        }
        f = next;
    }
    let mut out = std::io::BufWriter::new(std::fs::File::create(output)?);
    for p in &v {
        writeln!(out, "v {} {} {}", p[0], p[1], p[2])?;
    }
    for t in &f {
        writeln!(out, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1)?;
    }
    out.flush()?;
    println!("{}: {} vertices, {} triangles", output, v.len(), f.len());
    Ok(())
}
