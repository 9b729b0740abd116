//! How passes take paths through the stages: the two schedules, the trial that picks one on CPU devices, and the rows
//! a follow dispatch takes (the fused schedule's back-off when lavapipe's loop budget cuts a dispatch short). State
//! machines only; the integrator runs them.
use crate::constants::*;

/// How a pass takes its paths through the stages. Both give the same bytes for a seed (tests/schedule.rs).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Schedule {
    /// generate, then extend, shade and connect once per bounce, with paths compacted through queues in between:
    /// the default on GPUs, where stages with full, coherent waves matter most.
    Wavefront,
    /// One `follow` dispatch: each invocation takes one pixel's samples from camera to end with the path state in
    /// registers, starting its next sample as soon as a path ends. No path state goes through memory (on lavapipe
    /// each path-state store is a loop of scalar stores), but a subgroup runs a shadow-ray traversal whenever any of
    /// its lanes has a shadow ray, where connect runs only compacted ones. On lavapipe the Cornell box renders 1.25x
    /// as many samples per second this way; scenes where fewer bounces cast shadow rays (glass, glossy and textured
    /// ones) run 1.2-1.45x slower.
    Fused,
}

/// How passes pick their schedule.
#[derive(Clone, Copy, Debug)]
pub(super) enum ScheduleChoice {
    Fixed(Schedule),
    /// On CPU devices, where which is faster depends on the scene: passes 0 and 1 run the wavefront, 2 and 3 the
    /// fused schedule (each a quarter of a wavefront pass: `trial_rows`); the second of each pair (the first
    /// compiles) is timed, GPU time per path, and the faster is kept. Renders of one or two passes never build the fused pipelines. Both give the same bytes, so switching
    /// between passes changes nothing but speed.
    Trial {
        passes: u32,
        /// Wavefront, fused.
        ns_per_path: [f64; 2],
    },
}

impl ScheduleChoice {
    pub(super) fn trial() -> Self {
        ScheduleChoice::Trial {
            passes: 0,
            ns_per_path: [0.0; 2],
        }
    }

    pub(super) fn current(&self) -> Schedule {
        match *self {
            ScheduleChoice::Fixed(s) => s,
            ScheduleChoice::Trial { passes: 0..=1, .. } => Schedule::Wavefront,
            ScheduleChoice::Trial { passes: 2..=3, .. } => Schedule::Fused,
            ScheduleChoice::Trial {
                ns_per_path: [w, f], ..
            } if f < w => Schedule::Fused,
            ScheduleChoice::Trial { .. } => Schedule::Wavefront,
        }
    }

    /// Whether the next pass is one of the trial's four.
    pub(super) fn in_trial(&self) -> bool {
        matches!(self, ScheduleChoice::Trial { passes: 0..=3, .. })
    }

    /// The sample rows a fused trial pass takes, of the `fit` a wavefront pass takes: a quarter (one at least). A
    /// fused pass may hold every remaining sample, and the trial's first fused pass took the rest of a render on the
    /// schedule that may be the slower (on a textured scene, 60 % of a 64-spp render ran fused at 0.53x the
    /// wavefront's speed before the trial could decide); now the trial's fused half is half a wavefront pass, and
    /// the rest runs on the faster schedule. The wavefront's trial passes keep their size, so renders of one or two
    /// passes still never build the fused pipelines.
    pub(super) fn trial_rows(fit: u32) -> u32 {
        (fit / 4).max(1)
    }

    /// Counts a pass that ran `current()` and took `ns` of GPU time for `paths` paths.
    pub(super) fn record(&mut self, ns: f64, paths: u32) {
        if let ScheduleChoice::Trial { passes, ns_per_path } = self {
            match *passes {
                1 => ns_per_path[0] = ns / paths.max(1) as f64,
                3 => ns_per_path[1] = ns / paths.max(1) as f64,
                _ => {}
            }
            *passes = passes.saturating_add(1);
        }
    }
}

/// Sample rows a follow dispatch takes: FOLLOW_SAMPLES to begin with, doubled after each fused pass up to `max`, and
/// halved (with `max` lowered to it for good) when lavapipe's loop budget cut a dispatch short.
#[derive(Clone, Copy, Debug)]
pub(super) struct FollowRows {
    pub rows: u32,
    max: u32,
}

impl Default for FollowRows {
    fn default() -> Self {
        FollowRows {
            rows: FOLLOW_SAMPLES,
            max: FOLLOW_ROWS_MAX,
        }
    }
}

impl FollowRows {
    /// After a cut dispatch that took `taken` rows (a pass may hold fewer than `rows`): the rows to run the pass
    /// fused again with, or None when it is already at the fewest and must run as a wavefront.
    pub(super) fn after_cut(&mut self, taken: u32) -> Option<u32> {
        if taken <= FOLLOW_SAMPLES {
            return None;
        }
        self.rows = (taken / 2).max(FOLLOW_SAMPLES);
        self.max = self.rows;
        Some(self.rows)
    }

    pub(super) fn after_fused_pass(&mut self) {
        self.rows = (2 * self.rows).min(self.max);
    }
}

#[cfg(test)]
mod tests {
    use super::{FollowRows, Schedule, ScheduleChoice};
    use crate::constants::{FOLLOW_ROWS_MAX, FOLLOW_SAMPLES};

    /// The trial runs each schedule twice, times the second run of each, and keeps the faster per path.
    #[test]
    fn the_schedule_trial_keeps_the_faster_per_path() {
        for (wave_ns, fused_ns, want) in [(2.0e6, 1.0e6, Schedule::Fused), (1.0e6, 2.0e6, Schedule::Wavefront)] {
            let mut c = ScheduleChoice::trial();
            let mut ran = Vec::new();
            for pass in 0..6 {
                let s = c.current();
                ran.push(s);
                // The first pass of each schedule compiles: its time must not count.
                let ns = match (s, pass) {
                    (_, 0) | (_, 2) => 1e12,
                    (Schedule::Wavefront, _) => wave_ns,
                    (Schedule::Fused, _) => fused_ns,
                };
                c.record(ns, 1000);
            }
            assert_eq!(
                ran[..4],
                [
                    Schedule::Wavefront,
                    Schedule::Wavefront,
                    Schedule::Fused,
                    Schedule::Fused
                ]
            );
            assert_eq!(ran[4..], [want, want]);
        }
        let mut fixed = ScheduleChoice::Fixed(Schedule::Fused);
        fixed.record(1.0, 1);
        assert_eq!(fixed.current(), Schedule::Fused);
    }

    /// A fused trial pass takes a quarter of a wavefront pass's rows, one at least: never the rest of the render.
    #[test]
    fn fused_trial_passes_are_a_quarter_of_a_wavefront_pass() {
        assert_eq!(ScheduleChoice::trial_rows(13), 3);
        assert_eq!(ScheduleChoice::trial_rows(3), 1);
        assert_eq!(ScheduleChoice::trial_rows(0), 1);
        let mut c = ScheduleChoice::trial();
        for pass in 0..4 {
            assert!(c.in_trial(), "pass {pass} is the trial's");
            c.record(1.0, 1);
        }
        assert!(!c.in_trial());
        assert!(!ScheduleChoice::Fixed(Schedule::Fused).in_trial());
    }

    /// Rows double up to the cap, a cut halves what the dispatch took and caps it there, and at the fewest a cut
    /// asks for the wavefront.
    #[test]
    fn follow_rows_double_and_back_off() {
        let mut f = FollowRows::default();
        assert_eq!(f.rows, FOLLOW_SAMPLES);
        for _ in 0..8 {
            f.after_fused_pass();
        }
        assert_eq!(f.rows, FOLLOW_ROWS_MAX);
        assert_eq!(f.after_cut(FOLLOW_ROWS_MAX), Some(FOLLOW_ROWS_MAX / 2));
        f.after_fused_pass();
        assert_eq!(f.rows, FOLLOW_ROWS_MAX / 2, "never as many again after a cut");
        assert_eq!(f.after_cut(FOLLOW_SAMPLES + 2), Some(FOLLOW_SAMPLES));
        assert_eq!(f.after_cut(FOLLOW_SAMPLES), None);
    }
}
