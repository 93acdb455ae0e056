//! Sixteen paths in flight, their state lane by lane (structure of arrays), and the moves
//! between a lane and the one-path code's state.

use crate::render::integrator::{PathState, ShadowRay};
use crate::render::lanes::{F32s, Isa, U32s, Vec3s, WIDTH};
use crate::render::sampler::{next4_lanes, SampleStream};
use crate::render::PixelSample;
use crate::render::RenderScene;

/// Sixteen paths in flight, lane by lane.
#[derive(Default)]
pub(super) struct Group<I> {
    pub(super) o: Vec3s<I>,
    pub(super) d: Vec3s<I>,
    pub(super) throughput: Vec3s<I>,
    pub(super) indirect: Vec3s<I>,
    pub(super) prev_pdf: F32s<I>,
    pub(super) depth: U32s<I>,
    /// The sample streams' fields ([`SampleStream`]).
    pub(super) seed: U32s<I>,
    pub(super) index: U32s<I>,
    pub(super) draw: U32s<I>,
    /// Lanes whose previous bounce was a delta choice (camera rays count as one).
    pub(super) prev_delta: u32,
    /// The vertex each lane of the vector stage scatters at: position, geometric and
    /// shading normals (front side), albedo, and for glossy ones the coat's roughness
    /// and index of refraction.
    pub(super) p: Vec3s<I>,
    pub(super) ng: Vec3s<I>,
    pub(super) ns: Vec3s<I>,
    pub(super) color: Vec3s<I>,
    pub(super) alpha: F32s<I>,
    pub(super) eta: F32s<I>,
    /// Pending shadow rays (lanes in `shadow`), traced with the lane's next ray.
    pub(super) sh_o: Vec3s<I>,
    pub(super) sh_d: Vec3s<I>,
    pub(super) sh_tmax: F32s<I>,
    pub(super) sh_c: Vec3s<I>,
    pub(super) shadow: u32,
    /// Job (pixel × spp + sample) and G-buffer values of each lane's path.
    pub(super) job: [usize; WIDTH],
    pub(super) out: [PixelSample; WIDTH],
}

impl<I: Isa> Group<I> {
    /// Lane `l`'s path state.
    #[inline(always)]
    pub(super) fn path(&self, l: usize) -> PathState {
        PathState {
            stream: SampleStream {
                pixel_seed: self.seed.0[l],
                index_reversed: self.index.0[l],
                draw: self.draw.0[l],
            },
            throughput: self.throughput.lane(l),
            indirect: self.indirect.lane(l),
            prev_pdf: self.prev_pdf.0[l],
            prev_delta: self.prev_delta & (1 << l) != 0,
            depth: self.depth.0[l],
        }
    }

    /// Stores `path` as lane `l`'s state.
    #[inline(always)]
    pub(super) fn set_path(&mut self, l: usize, path: &PathState) {
        self.seed.0[l] = path.stream.pixel_seed;
        self.index.0[l] = path.stream.index_reversed;
        self.draw.0[l] = path.stream.draw;
        self.throughput.set_lane(l, path.throughput);
        self.indirect.set_lane(l, path.indirect);
        self.prev_pdf.0[l] = path.prev_pdf;
        self.prev_delta = (self.prev_delta & !(1 << l)) | (u32::from(path.prev_delta) << l);
        self.depth.0[l] = path.depth;
    }

    /// Starts the paths of the `fresh` lanes, whose sample streams are set, at pixel
    /// positions `(px, py)`: [`PathState::start`] and the test reference's `camera_ray`
    /// in lanes (the same bits).
    #[inline(always)]
    pub(super) fn start(&mut self, scene: &RenderScene, fresh: u32, (px, py): (F32s<I>, F32s<I>)) {
        let m = U32s::from_bitmask(fresh);
        let cam = next4_lanes(self.seed, self.index, self.draw);
        let (o, d) = scene.camera.ray_lanes((px + cam[0], py + cam[1]), (cam[2], cam[3]));
        // The path fields other than the stream, which are the same for every path.
        let start = PathState::start(SampleStream { pixel_seed: 0, index_reversed: 0, draw: 0 });
        self.o = Vec3s::select(m, o, self.o);
        self.d = Vec3s::select(m, d, self.d);
        self.draw = U32s::select(m, self.draw.wrapping_add(U32s::splat(1)), self.draw);
        self.throughput = Vec3s::select(m, Vec3s::splat(start.throughput), self.throughput);
        self.indirect = Vec3s::select(m, Vec3s::splat(start.indirect), self.indirect);
        self.prev_pdf = F32s::select(m, F32s::splat(start.prev_pdf), self.prev_pdf);
        self.depth = U32s::select(m, U32s::splat(start.depth), self.depth);
        self.prev_delta = (self.prev_delta & !fresh) | if start.prev_delta { fresh } else { 0 };
    }

    /// Makes `s` lane `l`'s pending shadow ray.
    #[inline(always)]
    pub(super) fn set_shadow(&mut self, l: usize, s: &ShadowRay) {
        self.sh_o.set_lane(l, s.origin);
        self.sh_d.set_lane(l, s.dir);
        self.sh_tmax.0[l] = s.tmax;
        self.sh_c.set_lane(l, s.contribution);
        self.shadow |= 1 << l;
    }

    /// Lane `l`'s pending shadow ray, if any (no longer pending).
    #[inline(always)]
    pub(super) fn take_shadow(&mut self, l: usize) -> Option<ShadowRay> {
        if self.shadow & (1 << l) == 0 {
            return None;
        }
        self.shadow &= !(1 << l);
        Some(ShadowRay {
            contribution: self.sh_c.lane(l),
            origin: self.sh_o.lane(l),
            dir: self.sh_d.lane(l),
            tmax: self.sh_tmax.0[l],
        })
    }
}
