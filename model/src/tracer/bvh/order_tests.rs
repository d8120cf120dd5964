//! The order a node's met lanes are walked in: where at most two lanes met, [`TwoMet`] and the
//! stack slots it fills must give the order the general insertion ([`insert_sorted`]) gives, nearer
//! entry first and a tie in lane order, for every pattern of met lanes and of entries (the walk's
//! order decides which nodes the cut skips, so a swap would cost time and change the counters).

use super::{insert_sorted, Lanes, Met, TwoMet};

/// The lanes met (`hit`) in the order the general insertion puts them.
fn inserted_order(hit: u32, near: &[f32; 4]) -> Vec<u32> {
    let mut out: Lanes = [Met::NONE; 4];
    let mut len = 0;
    for (l, &e) in near.iter().enumerate() {
        if hit >> l & 1 != 0 {
            let m = Met {
                entry: e as f64,
                index: l as u32,
                triangles: false,
            };
            insert_sorted(&mut out, &mut len, m);
        }
    }
    out[..len].iter().map(|m| m.index).collect()
}

/// Entries for four lanes: every order of three distinct values, ties included.
fn entry_patterns() -> Vec<[f32; 4]> {
    let values = [0.5f32, 1.0, 2.0];
    let mut out = Vec::new();
    for a in values {
        for b in values {
            for c in values {
                for d in values {
                    out.push([a, b, c, d]);
                }
            }
        }
    }
    out
}

#[test]
fn two_met_lanes_are_ordered_as_the_insertion_orders_them() {
    let mut checked = 0;
    for hit in 0u32..16 {
        if hit.count_ones() > 2 {
            assert!(TwoMet::of(hit, &[0.0; 4]).is_none(), "mask {hit:04b}");
            continue;
        }
        for near in entry_patterns() {
            let two = TwoMet::of(hit, &near).expect("at most two met");
            let expected = inserted_order(hit, &near);
            assert_eq!(two.count, expected.len(), "mask {hit:04b}");
            let firsts = [two.first as u32, two.second as u32];
            assert_eq!(
                firsts[..two.count],
                expected[..],
                "mask {hit:04b} near {near:?}"
            );
            // The stack pops its top first: the slots below the depth plus the count, read from
            // the top down, are the walk's order.
            let slots = two.on_stack().map(|l| l as u32);
            let popped: Vec<u32> = slots[..two.count].iter().rev().copied().collect();
            assert_eq!(popped, expected, "mask {hit:04b} near {near:?}");
            checked += 1;
        }
    }
    // 11 masks of at most two lanes, 81 patterns each.
    assert_eq!(checked, 11 * 81);
}
