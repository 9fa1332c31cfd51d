//! The ReSTIR DI frame as a schedule of passes over buffers, shared by the GPU and CPU
//! backends so both run exactly the same sequence. Two G-buffers alternate between
//! "current" and "previous"; three reservoir buffers rotate so that no pass reads the
//! buffer it writes. The temporal pass's result is the next frame's history; the spatial
//! passes only improve what this frame shows. (Feeding spatial results back made every
//! pixel's history a blend of its neighbours' and compounded the biased mode's darkening
//! frame after frame; it also let one unlucky visibility test empty a whole history.) By
//! default primary and initial run as one dispatch, and so do the last spatial pass and
//! shade (see kernels' `restir.rs`), with the same results as one dispatch each
//! (`RESTIR_SPLIT_PASSES`, which times every pass).
use kernels::types::{Camera, FrameParams, RESTIR_HISTORY_VALID, RESTIR_SPLIT_PASSES};

#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum RestirPass {
    Primary,
    Initial,
    Temporal,
    Spatial(u32),
    Shade,
    /// Primary and initial in one dispatch.
    PrimaryInitial,
    /// The last spatial pass (its index) and shade in one dispatch.
    SpatialShade(u32),
}

impl RestirPass {
    pub fn name(self) -> &'static str {
        match self {
            RestirPass::Primary => "primary",
            RestirPass::Initial => "initial",
            RestirPass::Temporal => "temporal",
            RestirPass::Spatial(_) => "spatial",
            RestirPass::Shade => "shade",
            RestirPass::SpatialShade(_) => "spatial+shade",
            RestirPass::PrimaryInitial => "primary+initial",
        }
    }

    /// The pass's SPIR-V entry point: its variant for plain scenes (see
    /// `integrator::plain_scene`) or the general one.
    pub fn entry_point(self, plain: bool) -> &'static str {
        let [general, plain_variant] = match self {
            RestirPass::Primary => ["entry::restir_primary", "entry::restir_primary_plain"],
            RestirPass::Initial => ["entry::restir_initial", "entry::restir_initial_plain"],
            RestirPass::Temporal => ["entry::restir_temporal", "entry::restir_temporal_plain"],
            RestirPass::Spatial(_) => ["entry::restir_spatial", "entry::restir_spatial_plain"],
            RestirPass::Shade => ["entry::restir_shade", "entry::restir_shade_plain"],
            RestirPass::SpatialShade(_) => [
                "entry::restir_spatial_shade",
                "entry::restir_spatial_shade_plain",
            ],
            RestirPass::PrimaryInitial => [
                "entry::restir_primary_initial",
                "entry::restir_primary_initial_plain",
            ],
        };
        if plain {
            plain_variant
        } else {
            general
        }
    }

    pub const ENTRY_POINTS: [RestirPass; 7] = [
        RestirPass::Primary,
        RestirPass::Initial,
        RestirPass::Temporal,
        RestirPass::Spatial(0),
        RestirPass::Shade,
        RestirPass::PrimaryInitial,
        RestirPass::SpatialShade(0),
    ];
}

/// Buffer indices a pass binds: G-buffers 0..2, reservoir buffers 0..3.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub struct Slots {
    pub g_cur: usize,
    pub g_prev: usize,
    pub res_in: usize,
    pub res_out: usize,
    pub res_prev: usize,
}

/// Which buffers hold the history; advanced once per frame.
#[derive(Clone, Debug, Default)]
pub struct RestirSchedule {
    parity: usize,
    prev: usize,
}

impl RestirSchedule {
    /// The passes of one frame with their buffers, fused (see the module's comment) unless
    /// `split`; the schedule then moves on a frame.
    pub fn frame(&mut self, spatial_passes: u32, split: bool) -> Vec<(RestirPass, Slots)> {
        let (g_cur, g_prev) = (self.parity, 1 - self.parity);
        let history = self.prev;
        // This frame's initial reservoirs, and its temporal result (the next history).
        let (initial, temporal) = ((history + 1) % 3, (history + 2) % 3);
        let slots = |res_in, res_out, res_prev| Slots {
            g_cur,
            g_prev,
            res_in,
            res_out,
            res_prev,
        };
        let mut plan = if split {
            vec![
                (RestirPass::Primary, slots(temporal, initial, history)),
                (RestirPass::Initial, slots(temporal, initial, history)),
            ]
        } else {
            vec![(
                RestirPass::PrimaryInitial,
                slots(temporal, initial, history),
            )]
        };
        plan.push((RestirPass::Temporal, slots(initial, temporal, history)));
        // Spatial passes ping-pong between the two buffers free by now (this frame's initial
        // reservoirs and the old history), leaving the temporal result alone. A pass that
        // reads no history binds its input there too (read-only twice is allowed); one that
        // writes no reservoir still binds a free buffer as its output.
        let free = [initial, history];
        let mut input = temporal;
        let fused_last = !split && spatial_passes > 0;
        let unfused = if fused_last {
            spatial_passes - 1
        } else {
            spatial_passes
        };
        for i in 0..unfused {
            let out = free[i as usize % 2];
            plan.push((RestirPass::Spatial(i), slots(input, out, input)));
            input = out;
        }
        let spare = if input == initial { history } else { initial };
        let shade = if fused_last {
            RestirPass::SpatialShade(unfused)
        } else {
            RestirPass::Shade
        };
        plan.push((shade, slots(input, spare, input)));
        self.prev = temporal;
        self.parity = 1 - self.parity;
        plan
    }
}

/// ReSTIR's host state, one owner for both backends: two G-buffers, three reservoir buffers
/// and the schedule that rotates them. `G` and `R` are the backend's buffers (`Vec`s on
/// the CPU, `wgpu::Buffer`s on the GPU), made on the first ReSTIR frame.
pub struct RestirState<G, R> {
    pub gbuffers: [G; 2],
    pub reservoirs: [R; 3],
    schedule: RestirSchedule,
}

impl<G, R> RestirState<G, R> {
    /// Buffers from `gbuffer(label)` and `reservoirs(label)`, history empty.
    pub fn new(gbuffer: impl Fn(&str) -> G, reservoirs: impl Fn(&str) -> R) -> Self {
        Self {
            gbuffers: [gbuffer("gbuffer a"), gbuffer("gbuffer b")],
            reservoirs: [
                reservoirs("reservoirs a"),
                reservoirs("reservoirs b"),
                reservoirs("reservoirs c"),
            ],
            schedule: RestirSchedule::default(),
        }
    }

    /// The passes of the next frame with their buffers, and each pass's parameters.
    pub fn frame(&mut self, params: &FrameParams) -> Vec<(RestirPass, Slots, FrameParams)> {
        let split = params.restir_flags & RESTIR_SPLIT_PASSES != 0;
        self.schedule
            .frame(params.spatial_passes, split)
            .into_iter()
            .map(|(pass, slots)| {
                let mut p = *params;
                if let RestirPass::Spatial(i) | RestirPass::SpatialShade(i) = pass {
                    p.spatial_pass = i;
                }
                (pass, slots, p)
            })
            .collect()
    }
}

/// A frame that continues from the one before, seen then from `prev_camera`: its temporal
/// pass may reuse that frame's reservoirs (reprojected). The first frame of a sequence, or
/// one after the history was dropped, has no such flag.
pub fn continue_history(params: &mut FrameParams, prev_camera: Camera) {
    params.restir_flags |= RESTIR_HISTORY_VALID;
    params.prev_camera = prev_camera;
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_never_read_what_they_write_and_history_carries_over() {
        let mut s = RestirSchedule::default();
        let mut last_temporal = None;
        for frame in 0..16 {
            let split = frame >= 8;
            let plan = s.frame(frame % 4, split);
            let passes: Vec<RestirPass> = plan.iter().map(|(p, _)| *p).collect();
            // Every pass runs once, in order; fused, primary with initial and the last
            // spatial pass with shade.
            let spatial = (0..frame % 4).map(RestirPass::Spatial);
            let first: &[RestirPass] = if split {
                &[RestirPass::Primary, RestirPass::Initial]
            } else {
                &[RestirPass::PrimaryInitial]
            };
            let n = frame % 4;
            let expected: Vec<RestirPass> = if split || n == 0 {
                first
                    .iter()
                    .copied()
                    .chain([RestirPass::Temporal])
                    .chain(spatial)
                    .chain([RestirPass::Shade])
                    .collect()
            } else {
                first
                    .iter()
                    .copied()
                    .chain([RestirPass::Temporal])
                    .chain(spatial.take(n as usize - 1))
                    .chain([RestirPass::SpatialShade(n - 1)])
                    .collect()
            };
            assert_eq!(passes, expected);
            for (pass, sl) in &plan {
                assert_ne!(sl.res_in, sl.res_out, "{pass:?}");
                assert_ne!(sl.res_prev, sl.res_out, "{pass:?}");
                assert_ne!(sl.g_cur, sl.g_prev);
            }
            // Each pass reads the reservoirs the one before wrote (primary writes none).
            for w in plan.windows(2).filter(|w| w[0].0 != RestirPass::Primary) {
                assert_eq!(
                    w[1].1.res_in, w[0].1.res_out,
                    "{:?} -> {:?}",
                    w[0].0, w[1].0
                );
            }
            let temporal = plan
                .iter()
                .find(|(p, _)| *p == RestirPass::Temporal)
                .unwrap()
                .1;
            if let Some(t) = last_temporal {
                assert_eq!(
                    temporal.res_prev, t,
                    "history is last frame's temporal result"
                );
            }
            // No spatial pass or shade overwrites the history of the next frame.
            for (pass, sl) in plan
                .iter()
                .skip_while(|(p, _)| *p != RestirPass::Temporal)
                .skip(1)
            {
                assert_ne!(
                    sl.res_out, temporal.res_out,
                    "{pass:?} overwrites the history"
                );
            }
            last_temporal = Some(temporal.res_out);
        }
    }
}
