//! Pass policy: how the schedule splits a depth's direct light into bounded shade → shadow
//! passes ([`shadow_passes`]), so the rows of one pass stay within a budget however many lights
//! the scene has.

use crate::queue::pass::{MAX_SHADOW_ROWS, ShadowPass};

/// The schedule's shade → shadow passes of a depth: the passes covering `hits` hits × `lights` lights with at most `budget` rows each (clamped
/// to `1..=MAX_SHADOW_ROWS`), in an order that keeps every sample's additions as an unsplit
/// pass makes them (each hit meets its lights in index order): all hits against blocks of
/// `budget / hits` lights; or, when the hits alone exceed the budget, blocks of `budget` hits
/// against one light at a time. Always at least one pass (the one that shades and emits); no
/// lights (shadows off) gives one pass without shadow rays.
pub fn shadow_passes(
    hits: usize,
    lights: usize,
    budget: usize,
) -> impl Iterator<Item = ShadowPass> {
    let budget = budget.clamp(1, MAX_SHADOW_ROWS);
    let (hit_block, light_block) = if hits == 0 || lights == 0 {
        (hits.max(1), lights.max(1))
    } else if hits <= budget {
        (hits, (budget / hits).min(lights))
    } else {
        (budget, 1)
    };
    (0..hits.max(1)).step_by(hit_block).flat_map(move |h| {
        (0..lights.max(1))
            .step_by(light_block)
            .map(move |l| ShadowPass {
                hits: h.min(hits)..(h + hit_block).min(hits),
                lights: l.min(lights)..(l + light_block).min(lights),
            })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_cover_every_hit_and_light_once_within_the_budget() {
        for (hits, lights, budget) in [
            (150, 40, 1000),
            (150, 40, usize::MAX),
            (5000, 3, 1000),
            (1000, 7, 1000),
            (7, 1, 1),
            (0, 5, 10),
            (10, 0, 10),
            (0, 0, 0),
        ] {
            let passes: Vec<_> = shadow_passes(hits, lights, budget).collect();
            assert!(!passes.is_empty());
            assert!(passes[0].is_first());
            assert_eq!(passes.iter().filter(|p| p.is_first()).count(), 1);
            let mut seen = vec![0u32; hits * lights];
            for p in &passes {
                assert!(p.rows() <= budget.max(1), "{p:?} over {budget}");
                for h in p.hits.clone() {
                    for l in p.lights.clone() {
                        seen[h * lights + l] += 1;
                    }
                }
            }
            assert!(seen.iter().all(|&n| n == 1), "{hits} × {lights}, {budget}");
            // Each hit meets its lights in index order.
            for h in 0..hits {
                let order: Vec<_> = passes
                    .iter()
                    .filter(|p| p.hits.contains(&h))
                    .flat_map(|p| p.lights.clone())
                    .collect();
                assert_eq!(order, (0..lights).collect::<Vec<_>>());
            }
        }
        assert_eq!(shadow_passes(150, 40, 1000).count(), 7, "6 lights a pass");
        assert_eq!(shadow_passes(5000, 3, 1000).count(), 15);
    }
}
