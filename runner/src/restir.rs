//! The ReSTIR DI frame as a schedule of passes over buffers, shared by the GPU and CPU
//! backends so both run exactly the same sequence. Two G-buffers alternate between
//! "current" and "previous"; three reservoir buffers rotate so that no pass reads the
//! buffer it writes, and the frame's final reservoirs become the next frame's history.
#[derive(Copy, Clone, Debug, PartialEq, Eq)]
pub enum RestirPass {
    Primary,
    Initial,
    Temporal,
    Spatial(u32),
    Shade,
}

impl RestirPass {
    pub fn name(self) -> &'static str {
        match self {
            RestirPass::Primary => "primary",
            RestirPass::Initial => "initial",
            RestirPass::Temporal => "temporal",
            RestirPass::Spatial(_) => "spatial",
            RestirPass::Shade => "shade",
        }
    }

    pub fn entry_point(self) -> &'static str {
        match self {
            RestirPass::Primary => "entry::restir_primary",
            RestirPass::Initial => "entry::restir_initial",
            RestirPass::Temporal => "entry::restir_temporal",
            RestirPass::Spatial(_) => "entry::restir_spatial",
            RestirPass::Shade => "entry::restir_shade",
        }
    }

    pub const ENTRY_POINTS: [RestirPass; 5] = [
        RestirPass::Primary,
        RestirPass::Initial,
        RestirPass::Temporal,
        RestirPass::Spatial(0),
        RestirPass::Shade,
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
    /// The passes of one frame with their buffers; the schedule then moves on a frame.
    pub fn frame(&mut self, spatial_passes: u32) -> Vec<(RestirPass, Slots)> {
        let (g_cur, g_prev) = (self.parity, 1 - self.parity);
        let res_prev = self.prev;
        let (mut a, mut b) = ((res_prev + 1) % 3, (res_prev + 2) % 3);
        let slots = |res_in, res_out| Slots { g_cur, g_prev, res_in, res_out, res_prev };
        let mut plan = vec![
            (RestirPass::Primary, slots(b, a)),
            (RestirPass::Initial, slots(b, a)),
            (RestirPass::Temporal, slots(a, b)),
        ];
        std::mem::swap(&mut a, &mut b); // the latest result is now in `a`
        for i in 0..spatial_passes {
            plan.push((RestirPass::Spatial(i), slots(a, b)));
            std::mem::swap(&mut a, &mut b);
        }
        plan.push((RestirPass::Shade, slots(a, b)));
        self.prev = a;
        self.parity = 1 - self.parity;
        plan
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn passes_never_read_what_they_write_and_history_carries_over() {
        let mut s = RestirSchedule::default();
        let mut last_final = None;
        for frame in 0..6 {
            let plan = s.frame(frame % 3);
            for (pass, sl) in &plan {
                assert_ne!(sl.res_in, sl.res_out, "{pass:?}");
                assert_ne!(sl.res_prev, sl.res_out, "{pass:?}");
                assert_ne!(sl.g_cur, sl.g_prev);
            }
            // Each pass reads what the one before wrote.
            for w in plan.windows(2).skip(1) {
                assert_eq!(w[1].1.res_in, w[0].1.res_out, "{:?} -> {:?}", w[0].0, w[1].0);
            }
            let final_res = plan.last().unwrap().1.res_in;
            if let Some(f) = last_final {
                assert_eq!(plan[0].1.res_prev, f, "history is last frame's final reservoirs");
            }
            last_final = Some(final_res);
        }
    }
}
