//! The collapse of a binary tree into wide nodes against an exhaustive search: on random trees,
//! the lanes it gives every wide node add up to the least total area any choice of at most four
//! lanes a node reaches, and every binary leaf is reached exactly once.

use super::{half_area, Collapse, Node};
use crate::tracer::prepare::BoundBox;

/// A deterministic generator (64-bit LCG, high bits).
struct Lcg(u64);

impl Lcg {
    fn below(&mut self, n: u64) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(1_442_695_040_888_963_407);
        (self.0 >> 33) % n
    }
}

/// A random binary tree of `leaves` leaves in the build's layout (node 0 the root, children after
/// their parent at `first` and `first + 1`), each node with a random box.
fn random_tree(rng: &mut Lcg, leaves: usize) -> Vec<Node> {
    let mut nodes = vec![node(rng, 0, 0)];
    // (node, leaves below it)
    let mut work = vec![(0usize, leaves)];
    let mut item = 0;
    while let Some((n, below)) = work.pop() {
        if below == 1 {
            let count = 1 + rng.below(4) as u32;
            nodes[n] = node(rng, item, count);
            item += 1;
            continue;
        }
        let left = 1 + rng.below(below as u64 - 1) as usize;
        let first = nodes.len();
        nodes[n].first = first as u32;
        nodes.push(node(rng, 0, 0));
        nodes.push(node(rng, 0, 0));
        work.push((first, left));
        work.push((first + 1, below - left));
    }
    nodes
}

fn node(rng: &mut Lcg, first: u32, count: u32) -> Node {
    let lo = [0; 3].map(|_| rng.below(100) as f32);
    let hi = lo.map(|x| x + 1.0 + rng.below(50) as f32);
    Node {
        bounds: BoundBox {
            lo,
            hi,
            pad_base: 0.0,
            pad_slope: 0.0,
        },
        first,
        count,
        triangles_only: true,
    }
}

fn area(nodes: &[Node], n: usize) -> f64 {
    let b = &nodes[n].bounds;
    half_area(&b.lo.map(f64::from), &b.hi.map(f64::from))
}

/// Every way to cover binary node `n`'s subtree with at most `k` lanes (each lane a node of it),
/// found by listing them all.
fn covers(nodes: &[Node], n: usize, k: usize) -> Vec<Vec<usize>> {
    let mut all = vec![vec![n]];
    if nodes[n].count == 0 {
        let left = nodes[n].first as usize;
        for a in covers(nodes, left, k) {
            for b in covers(nodes, left + 1, k) {
                if a.len() + b.len() <= k {
                    all.push([a.clone(), b].concat());
                }
            }
        }
    }
    all
}

/// The least total area of the wide nodes of `n`'s subtree with `n` a wide node, by exhaustive
/// search.
fn least(nodes: &[Node], n: usize) -> f64 {
    if nodes[n].count > 0 {
        return area(nodes, n);
    }
    let left = nodes[n].first as usize;
    let mut best = f64::INFINITY;
    for a in covers(nodes, left, 3) {
        for b in covers(nodes, left + 1, 4 - a.len()) {
            let cost: f64 = a.iter().chain(&b).map(|&m| least(nodes, m)).sum();
            best = best.min(cost);
        }
    }
    area(nodes, n) + best
}

/// The total area of the wide nodes the collapse makes of `n`'s subtree, and the binary leaves
/// it reaches.
fn collapsed(nodes: &[Node], plan: &Collapse, n: usize, leaves: &mut Vec<usize>) -> f64 {
    if nodes[n].count > 0 {
        leaves.push(n);
        return area(nodes, n);
    }
    let mut lanes = Vec::new();
    plan.lanes_of(nodes, n, &mut lanes);
    assert!((2..=4).contains(&lanes.len()), "{} lanes", lanes.len());
    area(nodes, n)
        + lanes
            .iter()
            .map(|&m| collapsed(nodes, plan, m, leaves))
            .sum::<f64>()
}

#[test]
fn the_collapse_reaches_the_least_total_area_of_wide_nodes() {
    let mut rng = Lcg(0xc011);
    for case in 0..300 {
        let leaves = 1 + rng.below(11) as usize;
        let nodes = random_tree(&mut rng, leaves);
        let plan = Collapse::of(&nodes);
        let mut reached = Vec::new();
        let total = collapsed(&nodes, &plan, 0, &mut reached);
        let best = least(&nodes, 0);
        assert!(
            (total - best).abs() <= 1e-9 * best,
            "case {case}: the collapse's area {total}, the least {best}"
        );
        reached.sort_unstable();
        let all: Vec<usize> = (0..nodes.len()).filter(|&n| nodes[n].count > 0).collect();
        assert_eq!(reached, all, "case {case}: every binary leaf once");
    }
}

#[test]
fn taking_grandchildren_alone_is_not_the_least_cover() {
    // A planted fault: the collapse's lanes replaced by the binary node's grandchildren (the
    // children where they are leaves). On random trees this costs more area somewhere.
    let mut rng = Lcg(0x9a4d);
    let mut worse = 0;
    for _ in 0..300 {
        let leaves = 2 + rng.below(10) as usize;
        let nodes = random_tree(&mut rng, leaves);
        let best = least(&nodes, 0);
        if grandchildren_area(&nodes, 0) > best * (1.0 + 1e-9) {
            worse += 1;
        }
    }
    assert!(worse > 0, "the exhaustive search tells the two apart");
}

fn grandchildren_area(nodes: &[Node], n: usize) -> f64 {
    if nodes[n].count > 0 {
        return area(nodes, n);
    }
    let left = nodes[n].first as usize;
    let mut lanes = Vec::new();
    for c in [left, left + 1] {
        if nodes[c].count > 0 {
            lanes.push(c);
        } else {
            lanes.extend([nodes[c].first as usize, nodes[c].first as usize + 1]);
        }
    }
    area(nodes, n)
        + lanes
            .iter()
            .map(|&m| grandchildren_area(nodes, m))
            .sum::<f64>()
}
