//! The layout built from obvhs's CWBVH: child boxes decoded once to full precision, leaf
//! children packed into fuller four-triangle packets, freed node slots filled with
//! grandchildren, and the nodes renumbered depth first.

use obvhs::aabb::Aabb;
use obvhs::cwbvh::CwBvh;

use super::super::triangle::TriEdges;
use super::{LaneFill, Node, Packet, WideBvh, LEAF};

impl Packet {
    /// The packet of leaf-order triangles `prims` (at most four) of `tris`.
    fn new(tris: &[TriEdges], prims: &[u32]) -> Self {
        let mut p = Packet { prim: [u32::MAX; 4], ..Default::default() };
        for (lane, &prim) in prims.iter().enumerate() {
            let tri = &tris[prim as usize];
            for a in 0..3 {
                p.v0[a][lane] = tri.v0[a];
                p.e1[a][lane] = tri.e1[a];
                p.e2[a][lane] = tri.e2[a];
            }
            p.prim[lane] = prim;
        }
        p
    }
}

/// Merges the leaf children of one node (box, triangles) into packets of up to four.
/// A CWBVH leaf holds at most three triangles, so most packets ran with lanes empty
/// (two fifths full on bunny and Sponza), and a packet costs the same test however full.
/// Two leaves merge when the surface area heuristic says it pays: a ray reaches a box
/// with probability in proportion to its area, so one test of the union box costs less
/// than the two separate tests when area(a ∪ b) < area(a) + area(b). The best such pair
/// merges first, until no pair fits in four lanes and pays.
fn pack_leaves(mut leaves: Vec<(Aabb, Vec<u32>)>) -> Vec<(Aabb, Vec<u32>)> {
    loop {
        let mut best: Option<(f32, usize, usize)> = None;
        for i in 0..leaves.len() {
            for j in i + 1..leaves.len() {
                if leaves[i].1.len() + leaves[j].1.len() > 4 {
                    continue;
                }
                let (a, b) = (&leaves[i].0, &leaves[j].0);
                let ratio = a.union(b).half_area() / (a.half_area() + b.half_area()).max(1e-30);
                if ratio < 1.0 && best.is_none_or(|(r, ..)| ratio < r) {
                    best = Some((ratio, i, j));
                }
            }
        }
        let Some((_, i, j)) = best else { return leaves };
        let (bounds, prims) = leaves.swap_remove(j);
        leaves[i].0 = leaves[i].0.union(&bounds);
        leaves[i].1.extend(prims);
    }
}

/// Fills the slots that packing freed: a node takes the children of its largest inner
/// child in that child's place while they fit in eight slots, so that a ray tests them
/// in the parent's node test instead of a further one. Parents come before children in
/// the CWBVH's order, so a pulled-up grandchild can be expanded in turn; the nodes this
/// leaves unreferenced are dropped by [`reachable`].
fn pull_up(lists: &mut [Vec<(Aabb, u32)>]) {
    for n in 0..lists.len() {
        loop {
            let free = 8 - lists[n].len();
            let pick = lists[n]
                .iter()
                .enumerate()
                .filter(|(_, (_, c))| c & LEAF == 0 && lists[*c as usize].len() <= free + 1)
                .max_by(|a, b| a.1 .0.half_area().total_cmp(&b.1 .0.half_area()))
                .map(|(i, _)| i);
            let Some(i) = pick else { break };
            let (_, child) = lists[n].swap_remove(i);
            let grandchildren = lists[child as usize].clone();
            lists[n].extend(grandchildren);
        }
    }
}

/// The nodes reachable from the root, renumbered in depth-first order (the order a
/// traversal meets them, which keeps a subtree's nodes together in memory).
fn reachable(mut lists: Vec<Vec<(Aabb, u32)>>) -> Vec<Vec<(Aabb, u32)>> {
    if lists.is_empty() {
        return lists;
    }
    let mut order = Vec::with_capacity(lists.len());
    let mut new_index = vec![u32::MAX; lists.len()];
    let mut stack = vec![0u32];
    while let Some(n) = stack.pop() {
        new_index[n as usize] = order.len() as u32;
        order.push(n);
        for &(_, c) in lists[n as usize].iter().rev() {
            if c & LEAF == 0 {
                stack.push(c);
            }
        }
    }
    order
        .into_iter()
        .map(|n| {
            let mut children = std::mem::take(&mut lists[n as usize]);
            for (_, c) in &mut children {
                if *c & LEAF == 0 {
                    *c = new_index[*c as usize];
                }
            }
            children
        })
        .collect()
}

impl WideBvh {
    /// Decodes `bvh` (built over `tris`, which are in its leaf order), packing the leaf
    /// children of each node into as few four-lane packets as pays (see [`pack_leaves`]).
    pub(in crate::render::accel) fn build(bvh: &CwBvh, tris: &[TriEdges]) -> Self {
        let mut out = WideBvh { nodes: Vec::with_capacity(bvh.nodes.len()), packets: Vec::new() };
        // Each node's children as (box, reference) before they are laid out.
        let mut lists: Vec<Vec<(Aabb, u32)>> = Vec::with_capacity(bvh.nodes.len());
        for cw in &bvh.nodes {
            let ext = cw.compute_extent();
            let quantised = [
                &cw.child_min_x,
                &cw.child_max_x,
                &cw.child_min_y,
                &cw.child_max_y,
                &cw.child_min_z,
                &cw.child_max_z,
            ];
            let mut children = Vec::with_capacity(8);
            let mut leaves = Vec::with_capacity(8);
            for i in 0..8 {
                let meta = cw.child_meta[i];
                if meta == 0 {
                    continue;
                }
                let mut bounds = Aabb::empty();
                for (plane, q) in quantised.iter().enumerate() {
                    let axis = plane / 2;
                    // The CWBVH quantised a rounded difference, so its planes may sit a
                    // rounding inside the true bounds; a 4096th of a quantum and two
                    // ulps of the decoded plane outwards cover that and the decoding.
                    let x = cw.p[axis] + q[i] as f32 * ext[axis];
                    let pad = ext[axis] * (1.0 / 4096.0);
                    if plane % 2 == 0 {
                        bounds.min[axis] = (x - pad).next_down().next_down();
                    } else {
                        bounds.max[axis] = (x + pad).next_up().next_up();
                    }
                }
                let low = u32::from(meta & 0x1f);
                if low >= 24 {
                    let slot = low - 24;
                    debug_assert!(cw.imask & (1 << slot) != 0);
                    let child = cw.child_base_idx
                        + (u32::from(cw.imask) & ((1u32 << slot) - 1)).count_ones();
                    children.push((bounds, child));
                } else {
                    let first = cw.primitive_base_idx + low;
                    let count = (meta >> 5).count_ones();
                    leaves.push((bounds, (first..first + count).collect::<Vec<u32>>()));
                }
            }
            for (bounds, prims) in pack_leaves(leaves) {
                out.packets.push(Packet::new(tris, &prims));
                children.push((bounds, LEAF | (out.packets.len() as u32 - 1)));
            }
            lists.push(children);
        }
        pull_up(&mut lists);
        for children in reachable(lists) {
            let mut node = Node { planes: [[0.0; 8]; 6], child: [0; 8], valid: 0 };
            for (i, (bounds, child)) in children.into_iter().enumerate() {
                for axis in 0..3 {
                    node.planes[2 * axis][i] = bounds.min[axis];
                    node.planes[2 * axis + 1][i] = bounds.max[axis];
                }
                node.child[i] = child;
                node.valid |= 1 << i;
            }
            out.nodes.push(node);
        }
        out
    }

    /// How many of this tree's node and leaf lanes hold something.
    pub(in crate::render::accel) fn lane_fill(&self) -> LaneFill {
        LaneFill {
            node_lanes_used: self.nodes.iter().map(|n| u64::from(n.valid.count_ones())).sum(),
            node_lanes: 8 * self.nodes.len() as u64,
            leaf_lanes_used: self
                .packets
                .iter()
                .map(|p| p.prim.iter().filter(|&&i| i != u32::MAX).count() as u64)
                .sum(),
            leaf_lanes: 4 * self.packets.len() as u64,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::render::accel::Blas;
    use std::sync::Arc;

    /// Packing and pulling up keep every triangle exactly once, inside every box on the
    /// way to it (so a ray that hits it reaches it), with every node reachable and the
    /// lanes fuller than the CWBVH's three-per-leaf packets left them.
    #[test]
    fn packed_layout_keeps_every_triangle_inside_its_boxes() {
        let blas = Blas::build(Arc::new(crate::shapes::sphere(4))).unwrap();
        let wide = &blas.wide;
        let mut seen = vec![0u32; blas.tris.len()];
        let mut reached = vec![false; wide.nodes.len()];
        let mut stack = vec![(0u32, [f32::NEG_INFINITY, f32::INFINITY].repeat(3))];
        while let Some((n, bounds)) = stack.pop() {
            reached[n as usize] = true;
            let node = &wide.nodes[n as usize];
            assert_eq!(node.valid & (node.valid + 1), 0, "node {n}: slots not packed low");
            for i in 0..node.valid.count_ones() as usize {
                // What a ray must pass to get here: this box within all its ancestors'.
                let b: Vec<f32> = (0..6)
                    .map(|p| {
                        let x = node.planes[p][i];
                        if p % 2 == 0 {
                            x.max(bounds[p])
                        } else {
                            x.min(bounds[p])
                        }
                    })
                    .collect();
                let child = node.child[i];
                if child & LEAF == 0 {
                    stack.push((child, b));
                    continue;
                }
                let packet = &wide.packets[(child & !LEAF) as usize];
                for lane in (0..4).filter(|&l| packet.prim[l] != u32::MAX) {
                    let prim = packet.prim[lane];
                    seen[prim as usize] += 1;
                    let t = &blas.tris[prim as usize];
                    for v in [t.v0, t.v0 + t.e1, t.v0 + t.e2] {
                        for axis in 0..3 {
                            assert!(v[axis] >= b[2 * axis] && v[axis] <= b[2 * axis + 1]);
                        }
                    }
                }
            }
        }
        assert!(seen.iter().all(|&n| n == 1), "a triangle is missing or repeated");
        assert!(reached.iter().all(|&r| r), "unreachable nodes were kept");
        let fill = wide.lane_fill();
        assert!(fill.leaf_occupancy() > 0.6, "leaf lanes {:.2}", fill.leaf_occupancy());
    }
}
