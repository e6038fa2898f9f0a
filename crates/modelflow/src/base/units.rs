//! The length unit of a scene's world coordinates (`"units"` in the scene file) and the one way
//! every output shows a length: in millimetres when the scene says its unit, in "scene units"
//! when it does not. The terminal, `eval` and the report all go through [`Length`], so a user
//! never sees the same error in two units.

use serde::{Deserialize, Serialize};

/// The unit of a scene's world coordinates.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Units {
    #[serde(rename = "m")]
    Metres,
    #[serde(rename = "cm")]
    Centimetres,
    #[serde(rename = "mm")]
    Millimetres,
}

impl Units {
    /// Millimetres in one unit.
    pub fn millimetres(self) -> f64 {
        match self {
            Units::Metres => 1000.0,
            Units::Centimetres => 10.0,
            Units::Millimetres => 1.0,
        }
    }

    /// The unit as the scene file spells it.
    pub fn name(self) -> &'static str {
        match self {
            Units::Metres => "m",
            Units::Centimetres => "cm",
            Units::Millimetres => "mm",
        }
    }
}

impl std::str::FromStr for Units {
    type Err = String;
    fn from_str(s: &str) -> std::result::Result<Self, String> {
        match s {
            "m" => Ok(Units::Metres),
            "cm" => Ok(Units::Centimetres),
            "mm" => Ok(Units::Millimetres),
            _ => Err(format!("unknown unit {s:?}: expected m, cm or mm")),
        }
    }
}

/// How lengths of one scene are shown: [`Length::unit`] names the unit and
/// [`Length::value`] converts a length in scene units into it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Length {
    factor: f64,
    unit: &'static str,
}

impl Length {
    /// Millimetres when the scene's unit is known, scene units otherwise.
    pub fn of(units: Option<Units>) -> Length {
        match units {
            Some(u) => Length {
                factor: u.millimetres(),
                unit: "mm",
            },
            None => Length {
                factor: 1.0,
                unit: "scene units",
            },
        }
    }

    /// A length in scene units, in the shown unit.
    pub fn value(&self, scene_units: f64) -> f64 {
        self.factor * scene_units
    }

    /// A length in scene units, in the shown unit, written with `significant` digits.
    pub fn show(&self, scene_units: f64) -> String {
        significant(self.value(scene_units))
    }

    /// The shown unit: `mm` or `scene units`.
    pub fn unit(&self) -> &'static str {
        self.unit
    }
}

/// `v` with at least three significant digits and no more decimals than that takes (at most
/// nine): 1749, 13.6, 0.0102, 0.00000140. A length in a scene of any unit reads the same way.
pub fn significant(v: f64) -> String {
    if v == 0.0 || !v.is_finite() {
        return format!("{v}");
    }
    let exponent = v.abs().log10().floor() as i32;
    let digits = (2 - exponent).clamp(0, 9) as usize;
    let shown = format!("{v:.digits$}");
    // 0.0099999 rounds up to 0.01000: one decimal fewer, as 0.0100 would be written.
    let rounded_up = shown
        .parse::<f64>()
        .is_ok_and(|r| r.abs() >= 10f64.powi(exponent + 1));
    if rounded_up && digits > 0 {
        let digits = digits - 1;
        format!("{v:.digits$}")
    } else {
        shown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_show_three_significant_digits_whatever_their_size() {
        assert_eq!(significant(1748.5125), "1749");
        assert_eq!(significant(13.631962), "13.6");
        assert_eq!(significant(0.010000), "0.0100");
        assert_eq!(significant(0.000014), "0.0000140");
        assert_eq!(significant(-2.5), "-2.50");
        assert_eq!(significant(0.0), "0");
        // Rounding up past a power of ten keeps three digits, not four.
        assert_eq!(significant(0.009_999_999), "0.0100");
        assert_eq!(significant(99.96), "100");
    }

    #[test]
    fn lengths_show_in_millimetres_when_the_unit_is_known() {
        let m = Length::of(Some(Units::Metres));
        assert_eq!((m.value(0.0123), m.unit()), (12.3, "mm"));
        assert_eq!(Length::of(Some(Units::Centimetres)).value(2.5), 25.0);
        assert_eq!(Length::of(Some(Units::Millimetres)).value(2.5), 2.5);
        let s = Length::of(None);
        assert_eq!((s.value(0.0123), s.unit()), (0.0123, "scene units"));
        assert_eq!("cm".parse::<Units>(), Ok(Units::Centimetres));
        assert!("inch".parse::<Units>().unwrap_err().contains("m, cm or mm"));
    }
}
