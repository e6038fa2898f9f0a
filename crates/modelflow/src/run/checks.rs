//! The frames to check of a run folder, read back: its `log.jsonl` lines and its manifest's
//! `last_frame_check` through the tracker's rules (`tracker::health`), for any range of frames
//! in it. What `track` said while it ran, available afterwards to the report and to programs.

use super::{read_frame_log, FrameLog, LastFrameCheck, Manifest, MANIFEST};
use crate::error::Result;
use crate::tracker::{Checks, FrameCheck, FrameReport};
use std::collections::BTreeMap;
use std::path::Path;

/// The frames of `first..=last` that the tracker's checks flag in the run folder `dir`, and why,
/// with `first` taken as the given mesh (never flagged). The last frame's verdict is the next
/// frame's log line when the run goes on past `last`, or else the manifest's
/// `last_frame_check` for that frame. A frame logged twice (a resumed run) counts by its last
/// line. `None` when the folder has no tracker log line in the range (the baseline's, a bare
/// folder of meshes).
pub fn frames_to_check(dir: &Path, first: u32, last: u32) -> Result<Option<Vec<FrameCheck>>> {
    checks_in(dir, &read_frame_log(dir)?, first, last)
}

/// [`frames_to_check`] with the folder's log lines already read.
pub(crate) fn checks_in(
    dir: &Path,
    lines: &[FrameLog],
    first: u32,
    last: u32,
) -> Result<Option<Vec<FrameCheck>>> {
    let mut by_frame: BTreeMap<u32, &FrameReport> = BTreeMap::new();
    let mut after = None;
    for l in lines {
        if let Some(r) = l.model_flow() {
            if (first..=last).contains(&l.frame) {
                by_frame.insert(l.frame, r);
            } else if l.frame == last + 1 {
                after = Some(r);
            }
        }
    }
    if by_frame.is_empty() {
        return Ok(None);
    }
    let mut checks = Checks::default();
    for (f, r) in &by_frame {
        checks.add(*f, first, r);
    }
    let verdict = match after {
        Some(r) => Some(LastFrameCheck::of_report(last, r)),
        None => {
            let manifest = dir.join(MANIFEST);
            let check = if manifest.is_file() {
                Manifest::read(&manifest)?.last_frame_check
            } else {
                None
            };
            check.filter(|c| c.frame == last)
        }
    };
    if let Some(v) = verdict {
        checks.judge_last(first, &v);
    }
    Ok(Some(checks.into_frames()))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A tracker log for frames 1..=5 in which frame 4's templates show the cameras
    /// contradicting frame 3's solution.
    fn log(dir: &Path) {
        let text: String = (1..=5u32)
            .map(|f| {
                let share = if f == 4 { 0.4 } else { 0.02 };
                format!(
                    "{{\"frame\": {f}, \"seconds\": 0.1, \"load_seconds\": 0, \"wall_seconds\": 0.1, \
                     \"method\": \"model_flow\", \"iterations\": 9, \"cost_before\": 1e-3, \
                     \"cost_after\": 1e-4, \"pixels\": 5000, \"contradicted_share\": {share}, \
                     \"contradicted_at_first\": 0.02, \"information_share\": 0.7, \
                     \"stop\": \"converged\", \"predicted\": false, \"stalled\": false, \
                     \"timing\": {{\"pyramids\": 0, \"patches\": 0, \"solve\": 0.1}}, \"levels\": []}}\n"
                )
            })
            .collect();
        std::fs::write(dir.join(super::super::LOG), text).unwrap();
    }

    #[test]
    fn a_range_of_a_run_is_judged_up_to_its_last_frame_by_the_line_after_it() {
        let dir = tempfile::tempdir().unwrap();
        log(dir.path());
        let frames = |first, last| -> Vec<u32> {
            frames_to_check(dir.path(), first, last)
                .unwrap()
                .unwrap()
                .iter()
                .map(|c| c.frame)
                .collect()
        };
        // The whole run: frame 3's solution is contradicted, and frame 4 started from it.
        assert_eq!(frames(0, 5), [3, 4]);
        // Frames 0..=3 only: frame 4's line still judges frame 3, the range's last.
        assert_eq!(frames(0, 3), [3]);
        // From frame 3 on, frame 3 is the given mesh: never flagged; frame 4 still is.
        assert_eq!(frames(3, 5), [4]);
        // Frames 0..=2: nothing.
        assert!(frames(0, 2).is_empty());
        // A folder without a tracker log has no checks.
        let empty = tempfile::tempdir().unwrap();
        assert!(frames_to_check(empty.path(), 0, 5).unwrap().is_none());
    }
}
