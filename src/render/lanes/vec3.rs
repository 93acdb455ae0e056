//! Three-component vectors of lanes, with glam's `Vec3` operations in glam's order.

use std::ops::{Add, Mul, Neg, Sub};

use super::{F32s, Isa, Mask};

/// Sixteen 3-vectors, component by component, with glam's `Vec3` arithmetic (same
/// operations in the same order, so the same bits).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Vec3s<I> {
    pub x: F32s<I>,
    pub y: F32s<I>,
    pub z: F32s<I>,
}

impl<I: Isa> Vec3s<I> {
    #[inline(always)]
    pub fn splat(v: glam::Vec3) -> Self {
        Self { x: F32s::splat(v.x), y: F32s::splat(v.y), z: F32s::splat(v.z) }
    }

    #[inline(always)]
    pub fn lane(&self, i: usize) -> glam::Vec3 {
        glam::Vec3::new(self.x.0[i], self.y.0[i], self.z.0[i])
    }

    #[inline(always)]
    pub fn set_lane(&mut self, i: usize, v: glam::Vec3) {
        (self.x.0[i], self.y.0[i], self.z.0[i]) = (v.x, v.y, v.z);
    }

    /// `(x·x') + (y·y') + (z·z')`, as glam.
    #[inline(always)]
    pub fn dot(self, o: Self) -> F32s<I> {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    #[inline(always)]
    pub fn scale(self, s: F32s<I>) -> Self {
        Self { x: self.x * s, y: self.y * s, z: self.z * s }
    }

    #[inline(always)]
    pub fn div_by(self, s: F32s<I>) -> Self {
        Self { x: self.x / s, y: self.y / s, z: self.z / s }
    }

    /// glam's `normalize`: the components times `1 / sqrt(self · self)`.
    #[inline(always)]
    pub fn normalize(self) -> Self {
        self.scale(F32s::splat(1.0) / self.dot(self).sqrt())
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        Self { x: self.x.abs(), y: self.y.abs(), z: self.z.abs() }
    }

    /// glam's `max_element`: `max(x, max(y, z))` with `a > b ? a : b`.
    #[inline(always)]
    pub fn max_element(self) -> F32s<I> {
        #[inline(always)]
        fn gt<I: Isa>(a: F32s<I>, b: F32s<I>) -> F32s<I> {
            F32s::select(a.gt(b), a, b)
        }
        gt(self.x, gt(self.y, self.z))
    }

    /// Lanes where all three components equal `o`'s.
    #[inline(always)]
    pub fn eq(self, o: Self) -> Mask<I> {
        self.x.eq(o.x) & self.y.eq(o.y) & self.z.eq(o.z)
    }

    #[inline(always)]
    pub fn select(mask: Mask<I>, a: Self, b: Self) -> Self {
        Self {
            x: F32s::select(mask, a.x, b.x),
            y: F32s::select(mask, a.y, b.y),
            z: F32s::select(mask, a.z, b.z),
        }
    }
}

/// A component-wise operator of `Vec3s`.
macro_rules! componentwise {
    ($trait:ident, $f:ident, $op:tt) => {
        impl<I: Isa> $trait for Vec3s<I> {
            type Output = Vec3s<I>;
            #[inline(always)]
            fn $f(self, o: Vec3s<I>) -> Vec3s<I> {
                Vec3s { x: self.x $op o.x, y: self.y $op o.y, z: self.z $op o.z }
            }
        }
    };
}

componentwise!(Add, add, +);
componentwise!(Sub, sub, -);
componentwise!(Mul, mul, *);

impl<I: Isa> Neg for Vec3s<I> {
    type Output = Vec3s<I>;
    #[inline(always)]
    fn neg(self) -> Vec3s<I> {
        Vec3s { x: -self.x, y: -self.y, z: -self.z }
    }
}
