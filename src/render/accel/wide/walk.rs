//! The traversals: closest hit (children nearest first, entries behind the closest hit
//! dropped), any hit (stops at the first), and both walked in turns.

use std::mem::MaybeUninit;

use super::{TriHit, WideBvh, WideRay, LEAF, STACK};
use crate::render::isa::Isa;

/// The traversal stack: `(child reference, entry distance)` for one ray, `packet.rs`'s
/// entries for rays in lanes; inline up to [`STACK`] entries (eight-wide trees are
/// shallow), on the heap beyond.
pub(super) struct Stack<T = (u32, f32)> {
    inline: [MaybeUninit<T>; STACK],
    len: usize,
    spill: Vec<T>,
}

impl<T: Copy> Stack<T> {
    #[inline(always)]
    pub(super) fn new() -> Self {
        // Not zeroed: a memset per ray cost 4 % of a bunny frame (and the array-repeat
        // form still compiled to one).
        // SAFETY: an array of `MaybeUninit` needs no initialisation.
        let inline = unsafe { MaybeUninit::<[MaybeUninit<T>; STACK]>::uninit().assume_init() };
        Self { inline, len: 0, spill: Vec::new() }
    }

    #[inline(always)]
    pub(super) fn push(&mut self, entry: T) {
        if self.len < STACK {
            self.inline[self.len] = MaybeUninit::new(entry);
            self.len += 1;
        } else {
            self.spill.push(entry);
        }
    }

    #[inline(always)]
    pub(super) fn pop(&mut self) -> Option<T> {
        if let Some(e) = self.spill.pop() {
            return Some(e);
        }
        if self.len == 0 {
            return None;
        }
        self.len -= 1;
        // SAFETY: entries below `len` were written by `push`.
        Some(unsafe { self.inline[self.len].assume_init() })
    }
}

impl WideBvh {
    /// The closest triangle the ray hits in (0, tmax).
    #[inline(always)]
    pub(in crate::render::accel) fn intersect<I: Isa>(
        &self,
        ray: &WideRay,
        tmax: f32,
    ) -> Option<TriHit> {
        let mut walk = ClosestWalk::new(self, tmax);
        while !walk.done {
            walk.step::<I>(self, ray);
        }
        walk.hit()
    }

    /// Whether any triangle blocks the ray in (0, tmax).
    #[inline(always)]
    pub(in crate::render::accel) fn occluded<I: Isa>(&self, ray: &WideRay, tmax: f32) -> bool {
        let mut walk = AnyWalk::new(self);
        while !walk.done {
            walk.step::<I>(self, ray, tmax);
        }
        walk.blocked
    }

    /// [`WideBvh::intersect`] of `closest` and [`WideBvh::occluded`] of `shadow`, the two
    /// walks advanced in turns, one node or leaf each. A path's bounce ray and shadow ray
    /// are independent, and on a tree larger than the caches each step waits on a load
    /// from memory: interleaved, the core has both loads in flight at once. Each walk
    /// takes the steps it takes alone, so the answers are the same bit for bit.
    #[inline(always)]
    pub(in crate::render::accel) fn intersect_and_occluded<I: Isa>(
        &self,
        (closest, tmax): (&WideRay, f32),
        (shadow, shadow_tmax): (&WideRay, f32),
    ) -> (Option<TriHit>, bool) {
        let mut a = ClosestWalk::new(self, tmax);
        let mut b = AnyWalk::new(self);
        while !a.done && !b.done {
            a.step::<I>(self, closest);
            b.step::<I>(self, shadow, shadow_tmax);
        }
        while !a.done {
            a.step::<I>(self, closest);
        }
        while !b.done {
            b.step::<I>(self, shadow, shadow_tmax);
        }
        (a.hit(), b.blocked)
    }
}

/// A closest-hit traversal in progress: children visited nearest first, stacked entries
/// behind the closest hit dropped unvisited.
struct ClosestWalk {
    best: TriHit,
    stack: Stack,
    /// The node or leaf the next step tests.
    current: u32,
    done: bool,
}

impl ClosestWalk {
    #[inline(always)]
    fn new(bvh: &WideBvh, tmax: f32) -> Self {
        let best = TriHit { t: tmax, prim: u32::MAX, u: 0.0, v: 0.0 };
        Self { best, stack: Stack::new(), current: 0, done: bvh.nodes.is_empty() }
    }

    #[inline(always)]
    fn hit(&self) -> Option<TriHit> {
        (self.best.prim != u32::MAX).then_some(self.best)
    }

    /// Tests the current node or leaf and moves to the next (or finishes).
    #[inline(always)]
    fn step<I: Isa>(&mut self, bvh: &WideBvh, ray: &WideRay) {
        let current = self.current;
        if current & LEAF == 0 {
            let node = &bvh.nodes[current as usize];
            let (mask, tnear) = node.hits::<I>(ray, self.best.t);
            if mask != 0 {
                let first = mask.trailing_zeros() as usize;
                if mask & (mask - 1) == 0 {
                    self.current = node.child[first];
                    return;
                }
                // Nearest first: sort the entered children by distance, farthest at
                // the bottom (stable, so ties keep child order).
                let mut order = [(0u32, 0.0f32); 8];
                let mut n = 0;
                let mut m = mask;
                while m != 0 {
                    let i = m.trailing_zeros() as usize;
                    m &= m - 1;
                    let entry = (node.child[i], tnear[i]);
                    let mut j = n;
                    while j > 0 && order[j - 1].1 < entry.1 {
                        order[j] = order[j - 1];
                        j -= 1;
                    }
                    order[j] = entry;
                    n += 1;
                }
                for &entry in &order[..n - 1] {
                    self.stack.push(entry);
                }
                self.current = order[n - 1].0;
                return;
            }
        } else {
            let packet = &bvh.packets[(current & !LEAF) as usize];
            let (mut mask, tuv) = packet.hits(ray, self.best.t);
            while mask != 0 {
                let i = mask.trailing_zeros() as usize;
                mask &= mask - 1;
                if tuv[0][i] < self.best.t {
                    self.best =
                        TriHit { t: tuv[0][i], prim: packet.prim[i], u: tuv[1][i], v: tuv[2][i] };
                }
            }
        }
        // Next: the nearest stacked entry not behind the closest hit.
        loop {
            let Some((r, t)) = self.stack.pop() else {
                self.done = true;
                return;
            };
            if t < self.best.t {
                self.current = r;
                return;
            }
        }
    }
}

/// An any-hit traversal in progress: it stops at the first triangle in range.
struct AnyWalk {
    stack: Stack,
    current: u32,
    blocked: bool,
    done: bool,
}

impl AnyWalk {
    #[inline(always)]
    fn new(bvh: &WideBvh) -> Self {
        Self { stack: Stack::new(), current: 0, blocked: false, done: bvh.nodes.is_empty() }
    }

    /// Tests the current node or leaf and moves to the next (or finishes).
    #[inline(always)]
    fn step<I: Isa>(&mut self, bvh: &WideBvh, ray: &WideRay, tmax: f32) {
        let current = self.current;
        if current & LEAF == 0 {
            let node = &bvh.nodes[current as usize];
            let (mut mask, _) = node.hits::<I>(ray, tmax);
            if mask != 0 {
                self.current = node.child[mask.trailing_zeros() as usize];
                mask &= mask - 1;
                while mask != 0 {
                    self.stack.push((node.child[mask.trailing_zeros() as usize], 0.0));
                    mask &= mask - 1;
                }
                return;
            }
        } else if bvh.packets[(current & !LEAF) as usize].hits(ray, tmax).0 != 0 {
            self.blocked = true;
            self.done = true;
            return;
        }
        match self.stack.pop() {
            Some((r, _)) => self.current = r,
            None => self.done = true,
        }
    }
}
