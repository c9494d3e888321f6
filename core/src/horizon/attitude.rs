//! What the horizon detector measures, as the estimator takes it: from the ground's detector
//! over the link, or from an on-board camera.

/// Roll and pitch measured from a camera image by the ground's horizon detector.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct HorizonAttitude {
    pub roll_rad: f32,
    pub pitch_rad: f32,
    /// In [0, 1].
    pub confidence: f32,
    /// When the image was captured, on the vehicle's executive clock.
    pub capture_t_ns: u64,
}
