//! Numbers read from text as C reads them, where ROS 2 reads them so: rcl types a parameter
//! value by `strtoll` and `strtod` ([`crate::params::ParamValue::from_yaml_scalar`]), and the
//! RMWs read their environment variables with `strtoll` (`ROS_DOMAIN_ID`,
//! `ZENOH_ROUTER_CHECK_ATTEMPTS`). One parser, so that they agree.

fn is_c_space(c: char) -> bool {
    matches!(c, ' ' | '\t' | '\n' | '\x0b' | '\x0c' | '\r')
}

/// Splits an optional sign off.
fn split_sign(s: &str) -> (bool, &str) {
    if let Some(rest) = s.strip_prefix('-') { (true, rest) } else { (false, s.strip_prefix('+').unwrap_or(s)) }
}

/// C's `strtoll(text, &end, 0)`, accepted only if it reads all of `text` without overflow.
pub(crate) fn strtoll(text: &str) -> Option<i64> {
    if text.is_empty() {
        return None;
    }
    let (negative, body) = split_sign(text.trim_start_matches(is_c_space));
    let hex = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X"));
    let (digits, radix) = match hex {
        Some(rest) if rest.starts_with(|c: char| c.is_ascii_hexdigit()) => (rest, 16),
        _ if body.starts_with('0') => (body, 8),
        _ => (body, 10),
    };
    if digits.is_empty() || !digits.chars().all(|c| c.is_digit(radix)) {
        return None;
    }
    let magnitude = i128::from(u64::from_str_radix(digits, radix).ok()?);
    i64::try_from(if negative { -magnitude } else { magnitude }).ok()
}

/// C's `strtod(text, &end)`, accepted only if it reads all of `text` and sets no `ERANGE`
/// (glibc: overflow to infinity, or underflow to zero or a subnormal).
pub(crate) fn strtod(text: &str) -> Option<f64> {
    if text.is_empty() {
        return None;
    }
    let (negative, body) = split_sign(text.trim_start_matches(is_c_space));
    let lower = body.to_ascii_lowercase();
    let magnitude = if lower == "inf" || lower == "infinity" {
        f64::INFINITY
    } else if lower == "nan"
        || lower
            .strip_prefix("nan(")
            .and_then(|r| r.strip_suffix(')'))
            .is_some_and(|inner| inner.chars().all(|c| c.is_ascii_alphanumeric() || c == '_'))
    {
        f64::NAN
    } else if let Some(hex) = body.strip_prefix("0x").or_else(|| body.strip_prefix("0X")) {
        c_hex_float(hex)?
    } else {
        c_decimal_float(body)?
    };
    Some(if negative { -magnitude } else { magnitude })
}

/// Counts leading ASCII digits of the given radix.
fn digit_run(s: &str, radix: u32) -> usize {
    s.chars().take_while(|c| c.is_digit(radix)).count()
}

/// Splits `mantissa` and the exponent digits (`e`/`p` already checked by the caller).
fn split_float(s: &str, radix: u32) -> Option<(&str, &str, Option<&str>)> {
    let int_len = digit_run(s, radix);
    let (int_part, rest) = s.split_at(int_len);
    let (frac_part, rest) = match rest.strip_prefix('.') {
        Some(after) => after.split_at(digit_run(after, radix)),
        None => ("", rest),
    };
    if int_part.is_empty() && frac_part.is_empty() {
        return None;
    }
    let exp_marker = if radix == 16 { ['p', 'P'] } else { ['e', 'E'] };
    let exponent = match rest.strip_prefix(exp_marker) {
        Some(exp) => {
            let (_, digits) = split_sign(exp);
            if digits.is_empty() || digit_run(digits, 10) != digits.len() {
                return None;
            }
            Some(exp)
        }
        None if rest.is_empty() => None,
        None => return None,
    };
    Some((int_part, frac_part, exponent))
}

fn c_decimal_float(body: &str) -> Option<f64> {
    let (int_part, frac_part, _) = split_float(body, 10)?;
    let value: f64 = body.parse().ok()?;
    let nonzero = int_part.chars().chain(frac_part.chars()).any(|c| c != '0');
    if value.is_infinite() || (nonzero && value.abs() < f64::MIN_POSITIVE) {
        return None;
    }
    Some(value)
}

fn c_hex_float(hex: &str) -> Option<f64> {
    let (int_part, frac_part, exponent) = split_float(hex, 16)?;
    let mut mantissa = 0.0f64;
    for c in int_part.chars().chain(frac_part.chars()) {
        mantissa = mantissa * 16.0 + f64::from(c.to_digit(16)?);
    }
    let exponent: i32 = match exponent {
        Some(e) => e.parse().ok()?,
        None => 0,
    };
    let frac_digits = i32::try_from(frac_part.len()).ok()?;
    let value = mantissa * 2f64.powi(exponent.checked_sub(4 * frac_digits)?);
    if value.is_infinite() || (mantissa != 0.0 && value < f64::MIN_POSITIVE) {
        return None;
    }
    Some(value)
}

/// C's `strtoll(text, NULL, 10)`: leading white space, a sign, the longest run of decimal
/// digits; 0 if there is none, saturated on overflow (as `ERANGE` leaves it).
pub(crate) fn strtoll_prefix(text: &str) -> i64 {
    let (negative, body) = split_sign(text.trim_start_matches(is_c_space));
    let digits = &body[..digit_run(body, 10)];
    if digits.is_empty() {
        return 0;
    }
    match digits.parse::<i64>() {
        Ok(n) if negative => -n,
        Ok(n) => n,
        Err(_) if negative => i64::MIN,
        Err(_) => i64::MAX,
    }
}
