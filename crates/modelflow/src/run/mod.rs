//! The run folder: what `track` and `baseline` write and `eval`, `report` and later exports
//! read. This module owns its layout (`layout`: `{frame:04}.obj` per frame, `log.jsonl`,
//! `run.json`), the manifest (`manifest`), the log schema (`log`), and the rules for opening a
//! folder (`folder`): it never destroys a file it did not write, never mixes two runs in one
//! folder, and resumes an interrupted run from its last complete frame. See
//! `docs/run-folder.md`; `checks` reads back the frames the tracker's rules flag. Knows nothing
//! of how frames are solved.

mod checks;
mod folder;
mod layout;
mod log;
mod manifest;

pub(crate) use checks::checks_in;
pub use checks::frames_to_check;
pub use folder::{write_run, OpenMode, Opened, RunFolder, RunOptions};
pub use layout::{
    confidence_file, frame_file, frame_number, read_confidence, read_run, write_confidence, LOG,
    MANIFEST,
};
pub use log::{read_frame_log, FrameDetail, FrameLog};
pub use manifest::{
    inputs_checksum, inputs_checksum_upto, made_from_another_scene, LastFrameCheck, Manifest,
    Method, Options, Resumption, SceneRecord, Status, RUN_FORMAT,
};
