//! The one place a setting's names are turned into text and back: `Display` and `FromStr`
//! from the setting's `ALL` and `name` (and `former_name`, for a setting renamed since).

/// `Display` and `FromStr` for `$ty` (named `$setting` in errors) from its `ALL` and
/// `name`; with `former`, a former name (`former_name`) is refused with the present one.
macro_rules! names {
    ($ty:ident, $setting:literal) => {
        $crate::names::names!(@impl $ty, $setting, |_: &str| None);
    };
    ($ty:ident, $setting:literal, former) => {
        $crate::names::names!(@impl $ty, $setting, |s: &str| $ty::ALL
            .iter()
            .find(|v| v.former_name() == s)
            .map(|v| v.name()));
    };
    (@impl $ty:ident, $setting:literal, $former:expr) => {
        impl std::fmt::Display for $ty {
            fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str(self.name())
            }
        }

        impl std::str::FromStr for $ty {
            type Err = $crate::DmpError;

            fn from_str(s: &str) -> Result<Self, $crate::DmpError> {
                if let Some(v) = $ty::ALL.iter().find(|v| v.name() == s) {
                    return Ok(*v);
                }
                Err($crate::DmpError::UnknownName {
                    setting: $setting,
                    given: s.to_string(),
                    known: $ty::ALL.iter().map(|v| v.name()).collect(),
                    now: ($former)(s),
                })
            }
        }
    };
}

pub(crate) use names;
