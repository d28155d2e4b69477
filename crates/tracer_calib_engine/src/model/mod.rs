//! The ways of fitting the mounting errors to a calibration-plate scan.
//!
//! - [`full`]: every raw sample, flats and corner arcs, five parameters
//!   `[alpha0, d, dL, cx, cy]`. Reaches the Cramér-Rao bound; the default.
//! - [`full_scale`]: the full model and the encoder scale `k`, six parameters
//!   `[alpha0, d, dL, k, cx, cy]`: for a tracer whose encoder scale is not known to
//!   better than the plate's size.
//! - [`paper`]: the seed paper's reduced model (its eqs. 5-8): sums of opposite samples
//!   differenced between neighbours remove `dL` and the plate centre, leaving
//!   `[alpha0, d]`; `dL` then follows in closed form. Exact on noise-free flat samples,
//!   but ill-conditioned: kept to reproduce the paper, not as the default.
//!
//! - [`tip`]: `full_tip` and `full_scale_tip`, a plate scan and a ring-gauge scan
//!   fitted together for the stylus tip's radius `ρ` too.
//!
//! Each is a [`crate::lm::Problem`].

pub mod full;
pub mod full_scale;
pub mod paper;
pub mod tip;
pub mod turntable;

use nalgebra::Vector2;
use std::fmt;

use super::shape::RoundedRect;

/// The calibration plate's known dimensions (its position is fitted).
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct PlateSpec {
    /// Side of the square, metres.
    pub side: f64,
    /// Radius of the rounded corners, metres.
    pub corner_radius: f64,
}

impl Default for PlateSpec {
    fn default() -> Self {
        PlateSpec { side: 0.045, corner_radius: 0.003 }
    }
}

impl PlateSpec {
    /// Check the dimensions make a plate: a positive side, `0 <= r < side/2`.
    pub fn validate(&self) -> Result<(), PlateError> {
        if !(self.side.is_finite() && self.side > 0.0) {
            return Err(PlateError::Side(self.side));
        }
        if !(self.corner_radius.is_finite() && self.corner_radius >= 0.0 && self.corner_radius < self.side / 2.0) {
            return Err(PlateError::CornerRadius { side: self.side, corner_radius: self.corner_radius });
        }
        Ok(())
    }

    /// The plate grown by `g` all round: side `S + 2g`, corners `r + g` (the contour the
    /// centre of a tip of radius `g` follows round it, [`tip`]).
    pub fn grown(&self, g: f64) -> PlateSpec {
        PlateSpec { side: self.side + 2.0 * g, corner_radius: self.corner_radius + g }
    }

    /// The plate placed with its centre at `center`.
    pub fn at(&self, center: Vector2<f64>) -> RoundedRect {
        RoundedRect::plate(self.side, self.corner_radius, center)
    }
}

/// Why plate dimensions make no plate ([`PlateSpec::validate`]): which dimension is wrong.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum PlateError {
    /// The side is not a positive length.
    #[error("plate side must be a positive length in metres, got {0}")]
    Side(f64),
    /// The corner radius is negative, or not less than half the side.
    #[error("plate corner radius must be at least 0 and less than half the side ({} m), got {corner_radius}", .side / 2.0)]
    CornerRadius {
        /// The plate's side, metres.
        side: f64,
        /// The corner radius given, metres.
        corner_radius: f64,
    },
}

/// How one sample's length `q` moves with each input a fit takes as known: the
/// artefacts' certified sizes, and the tip radius and encoder scale in force when the
/// model does not fit them. Each brings a type B part to the covariance
/// ([`crate::calibrate`](mod@crate::calibrate), GUM 5.1).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct InputDerivatives {
    /// `∂q/∂S`, the plate's side (corner radius kept): `(|N_x| + |N_y|)/(2 N·u)`.
    pub side: f64,
    /// `∂q/∂r`, the plate's corner radius (side kept): a corner's arc grows by `dr`
    /// while its centre moves in by `(dr, dr)`, so the contour moves along its normal by
    /// `(1 - (|N_x| + |N_y|)) dr`; `∂q/∂r = ∂q/∂g - 2 ∂q/∂S` (0 on a flat).
    pub corner: f64,
    /// `∂q/∂D`, the ring gauge's diameter: `1/(2 N·u)` on the ring.
    pub diameter: f64,
    /// `∂q/∂ρ` of a tip radius taken as known: the plate traced from outside is seen
    /// grown by `ρ` all round, `1/(N·u)`.
    pub tip: f64,
    /// The length the encoder read (`∂r/∂k₀ = -rho/k₀` for a scale `k₀` taken as known).
    pub rho: f64,
}

/// Which model fits the calibration.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum ModelKind {
    #[default]
    Full,
    Paper,
    /// The full model and the encoder scale.
    #[serde(rename = "full_scale")]
    FullScale,
    /// The full model and the tip radius, from a plate and a ring-gauge scan.
    #[serde(rename = "full_tip")]
    FullTip,
    /// The full model, the encoder scale and the tip radius.
    #[serde(rename = "full_scale_tip")]
    FullScaleTip,
}

impl ModelKind {
    /// Every model, in the order the documentation names them.
    pub const ALL: [ModelKind; 5] =
        [ModelKind::Full, ModelKind::Paper, ModelKind::FullScale, ModelKind::FullTip, ModelKind::FullScaleTip];

    /// Does this model fit the encoder scale?
    pub fn fits_scale(self) -> bool {
        matches!(self, ModelKind::FullScale | ModelKind::FullScaleTip)
    }

    /// Does this model fit the stylus tip's radius (from a ring-gauge scan)?
    pub fn fits_tip(self) -> bool {
        matches!(self, ModelKind::FullTip | ModelKind::FullScaleTip)
    }

    pub fn as_str(self) -> &'static str {
        match self {
            ModelKind::Full => "full",
            ModelKind::Paper => "paper",
            ModelKind::FullScale => "full_scale",
            ModelKind::FullTip => "full_tip",
            ModelKind::FullScaleTip => "full_scale_tip",
        }
    }
}

impl fmt::Display for ModelKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

/// A name that is none of the models ([`ModelKind`]'s `FromStr`): the name given.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown model '{0}': expected 'full', 'paper', 'full_scale', 'full_tip' or 'full_scale_tip'")]
pub struct UnknownModel(pub String);

impl std::str::FromStr for ModelKind {
    type Err = UnknownModel;
    fn from_str(s: &str) -> Result<Self, UnknownModel> {
        match s {
            "full" => Ok(ModelKind::Full),
            "paper" => Ok(ModelKind::Paper),
            "full_scale" => Ok(ModelKind::FullScale),
            "full_tip" => Ok(ModelKind::FullTip),
            "full_scale_tip" => Ok(ModelKind::FullScaleTip),
            _ => Err(UnknownModel(s.to_string())),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plates_and_model_names_refused_in_words() {
        assert_eq!(PlateSpec::default().validate(), Ok(()));
        let e = PlateSpec { side: 0.0, corner_radius: 0.0 }.validate().unwrap_err();
        assert_eq!(e, PlateError::Side(0.0));
        assert_eq!(e.to_string(), "plate side must be a positive length in metres, got 0");
        let e = PlateSpec { side: 0.045, corner_radius: 0.03 }.validate().unwrap_err();
        assert_eq!(e, PlateError::CornerRadius { side: 0.045, corner_radius: 0.03 });
        assert_eq!(
            e.to_string(),
            "plate corner radius must be at least 0 and less than half the side (0.0225 m), got 0.03"
        );
        assert_eq!("full_tip".parse::<ModelKind>(), Ok(ModelKind::FullTip));
        let e = "magic".parse::<ModelKind>().unwrap_err();
        assert_eq!(e, UnknownModel("magic".into()));
        assert_eq!(
            e.to_string(),
            "unknown model 'magic': expected 'full', 'paper', 'full_scale', 'full_tip' or 'full_scale_tip'"
        );
    }
}
