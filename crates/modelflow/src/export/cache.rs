//! Point caches: PC2 (little-endian: the 12-byte signature `POINTCACHE2\0`, version 1, point
//! count, start frame, sample rate, sample count, then x y z as `f32` per point per sample) and
//! MDD (big-endian: frame count, point count, each frame's time in seconds, then x y z as `f32`
//! per point per frame). Both carry positions only; the topology is the OBJ written beside them.

use crate::base::mesh::Mesh;
use crate::error::{Error, Result};

/// The PC2 file of `frames`, which must be evenly spaced (sample rate = their spacing).
pub(crate) fn pc2(frames: &[(u32, Mesh)]) -> Result<Vec<u8>> {
    let step = frames.get(1).map_or(1, |f| f.0 - frames[0].0);
    if let Some(w) = frames.windows(2).find(|w| w[1].0 - w[0].0 != step) {
        return Err(Error::option(
            "frames",
            format!("{} after {}", w[1].0, w[0].0),
            format!("evenly spaced frames for PC2 (every {step}); MDD or USD take any"),
        ));
    }
    let points = frames[0].1.positions.len();
    let mut b = Vec::with_capacity(32 + frames.len() * points * 12);
    b.extend_from_slice(b"POINTCACHE2\0");
    b.extend_from_slice(&1i32.to_le_bytes());
    b.extend_from_slice(&(points as i32).to_le_bytes());
    b.extend_from_slice(&(frames[0].0 as f32).to_le_bytes());
    b.extend_from_slice(&(step as f32).to_le_bytes());
    b.extend_from_slice(&(frames.len() as i32).to_le_bytes());
    for (_, m) in frames {
        for p in &m.positions {
            for c in [p.x, p.y, p.z] {
                b.extend_from_slice(&(c as f32).to_le_bytes());
            }
        }
    }
    Ok(b)
}

/// The MDD file of `frames`, frame `f` at `(f - first) / fps` seconds.
pub(crate) fn mdd(frames: &[(u32, Mesh)], fps: f64) -> Vec<u8> {
    let points = frames[0].1.positions.len();
    let first = frames[0].0;
    let mut b = Vec::with_capacity(8 + frames.len() * (4 + points * 12));
    b.extend_from_slice(&(frames.len() as i32).to_be_bytes());
    b.extend_from_slice(&(points as i32).to_be_bytes());
    for (f, _) in frames {
        b.extend_from_slice(&(super::seconds(*f, first, fps) as f32).to_be_bytes());
    }
    for (_, m) in frames {
        for p in &m.positions {
            for c in [p.x, p.y, p.z] {
                b.extend_from_slice(&(c as f32).to_be_bytes());
            }
        }
    }
    b
}
