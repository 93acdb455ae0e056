//! Three-component vectors of lanes, with glam's `Vec3` operations in glam's order.

use std::ops::{Add, AddAssign, Mul, Neg, Sub};

use super::{F32s, Isa, Mask, WIDTH};

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

    /// The entries `i..i + WIDTH` of three planes (x, y, z).
    #[inline(always)]
    pub fn load(planes: &[&[f32]; 3], i: usize) -> Self {
        let [x, y, z] = planes;
        Self { x: F32s::load(x, i), y: F32s::load(y, i), z: F32s::load(z, i) }
    }

    /// [`Vec3s::load`] without the bounds checks.
    ///
    /// # Safety
    /// `i + WIDTH <= p.len()` for each plane `p`.
    #[inline(always)]
    pub unsafe fn load_unchecked(planes: &[&[f32]; 3], i: usize) -> Self {
        let [x, y, z] = planes;
        // SAFETY: as the caller guarantees.
        unsafe {
            Self {
                x: F32s::load_unchecked(x, i),
                y: F32s::load_unchecked(y, i),
                z: F32s::load_unchecked(z, i),
            }
        }
    }

    /// The components' lanes, x, y, z.
    #[inline(always)]
    pub fn to_array(self) -> [F32s<I>; 3] {
        [self.x, self.y, self.z]
    }

    /// The lanes as vectors.
    #[inline(always)]
    pub fn to_vec3s(self) -> [glam::Vec3; WIDTH] {
        std::array::from_fn(|i| self.lane(i))
    }

    /// Each component's [`F32s::sum`].
    #[inline(always)]
    pub fn sum(self) -> glam::Vec3 {
        glam::Vec3::new(self.x.sum(), self.y.sum(), self.z.sum())
    }

    /// Each component's [`F32s::masked`].
    #[inline(always)]
    pub fn masked(self, keep: Mask<I>) -> Self {
        Self { x: self.x.masked(keep), y: self.y.masked(keep), z: self.z.masked(keep) }
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

impl<I: Isa> AddAssign for Vec3s<I> {
    #[inline(always)]
    fn add_assign(&mut self, o: Vec3s<I>) {
        *self = *self + o;
    }
}

impl<I: Isa> Neg for Vec3s<I> {
    type Output = Vec3s<I>;
    #[inline(always)]
    fn neg(self) -> Vec3s<I> {
        Vec3s { x: -self.x, y: -self.y, z: -self.z }
    }
}
