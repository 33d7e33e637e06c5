//! Calibration: what turns pixels and frames into millimetres and seconds
//! for a run, and the systematics of that conversion.
//!
//! | file | what it holds |
//! | --- | --- |
//! | [`scale`] | mm/px: given, from free fall (pooled per camera set-up), or from the radius; the silhouette's edge offset; sizes that disagree within a set-up |
//! | [`free_fall`] | the curvature of a run's free flights, and its pool over a set-up |
//! | [`lens`] | radial lens distortion: a known k1 undone on the track, or its bound as a systematic |
//! | [`setup_infer`] | runs grouped into camera set-ups by what their images show |

pub mod free_fall;
pub mod lens;
pub mod scale;
pub mod setup_infer;
