//! The special functions the tests need: Student's t tail, ln Γ, the regularised incomplete beta, erfc.
/// Two-sided p-value of t under Student's t with df degrees of freedom (df infinite: the normal).
pub(super) fn t_two_sided(t: f64, df: f64) -> f64 {
    let t = t.abs();
    if t == 0.0 || t.is_nan() {
        return 1.0;
    }
    if t.is_infinite() {
        return 0.0;
    }
    if df.is_infinite() {
        return erfc(t / std::f64::consts::SQRT_2);
    }
    // From 500 df the incomplete beta's continued fraction slows (its terms grow with sqrt(df)), and Peizer and
    // Pratt's normalising transform of t is within 0.05 % of the exact p down to 1e-20 (checked against scipy).
    if df >= 500.0 {
        let z = (df - 2.0 / 3.0 + 0.1 / df) * ((t * t / df).ln_1p() / (df - 5.0 / 6.0)).sqrt();
        return erfc(z / std::f64::consts::SQRT_2);
    }
    // P(|T| > t) = I_x(df/2, 1/2) with x = df/(df+t²); 1-x is passed separately so tiny t²/df keeps its digits.
    let t2 = t * t;
    reg_inc_beta(0.5 * df, 0.5, df / (df + t2), t2 / (df + t2))
}

/// ln Γ(x) for x > 0 (the tests' chi-square p-values use it too).
pub fn ln_gamma(x: f64) -> f64 {
    // Lanczos, g = 7, 9 terms: about 1e-15 relative for x > 0.5, reflection below.
    const C: [f64; 9] = [
        0.999_999_999_999_809_9,
        676.520_368_121_885_1,
        -1_259.139_216_722_402_8,
        771.323_428_777_653_1,
        -176.615_029_162_140_6,
        12.507_343_278_686_905,
        -0.138_571_095_265_720_12,
        9.984_369_578_019_572e-6,
        1.505_632_735_149_311_6e-7,
    ];
    use std::f64::consts::PI;
    if x < 0.5 {
        return (PI / (PI * x).sin()).ln() - ln_gamma(1.0 - x);
    }
    let x = x - 1.0;
    let t = x + 7.5;
    let a = C[1..]
        .iter()
        .enumerate()
        .fold(C[0], |a, (i, c)| a + c / (x + i as f64 + 1.0));
    0.5 * (2.0 * PI).ln() + (x + 0.5) * t.ln() - t + a.ln()
}

/// The regularised incomplete beta I_x(a, b), given x and y = 1 - x.
pub(super) fn reg_inc_beta(a: f64, b: f64, x: f64, y: f64) -> f64 {
    if x <= 0.0 {
        return 0.0;
    }
    if y <= 0.0 {
        return 1.0;
    }
    let ln_x = if x > 0.5 { (-y).ln_1p() } else { x.ln() };
    let ln_y = if y > 0.5 { (-x).ln_1p() } else { y.ln() };
    let front = (a * ln_x + b * ln_y - (ln_gamma(a) + ln_gamma(b) - ln_gamma(a + b))).exp();
    // The continued fraction converges fast below the mean (a+1)/(a+b+2); above it, the symmetry I_x(a,b) =
    // 1 - I_y(b,a). The tails this module needs are always on the fast side.
    if x < (a + 1.0) / (a + b + 2.0) {
        front * beta_cf(a, b, x) / a
    } else {
        1.0 - front * beta_cf(b, a, y) / b
    }
}

/// The incomplete beta's continued fraction, by the modified Lentz method.
pub(super) fn beta_cf(a: f64, b: f64, x: f64) -> f64 {
    const TINY: f64 = 1e-300;
    let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
    let (qab, qap, qam) = (a + b, a + 1.0, a - 1.0);
    let mut c = 1.0;
    let mut d = 1.0 / guard(1.0 - qab * x / qap);
    let mut h = d;
    for m in 1..100_000 {
        let m = m as f64;
        let m2 = 2.0 * m;
        let aa = m * (b - m) * x / ((qam + m2) * (a + m2));
        d = 1.0 / guard(1.0 + aa * d);
        c = guard(1.0 + aa / c);
        h *= d * c;
        let aa = -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2));
        d = 1.0 / guard(1.0 + aa * d);
        c = guard(1.0 + aa / c);
        let del = d * c;
        h *= del;
        if (del - 1.0).abs() < 1e-15 {
            break;
        }
    }
    h
}

/// erfc(x) = Q(1/2, x²), the regularised upper incomplete gamma; accurate in the far tail, unlike 1 - erf.
pub(super) fn erfc(x: f64) -> f64 {
    if x < 0.0 {
        return 2.0 - erfc(-x);
    }
    let z = x * x;
    let a = 0.5;
    let front = (-z + a * z.ln() - ln_gamma(a)).exp();
    if z < a + 1.0 {
        // Series for P(a, z); Q = 1 - P loses nothing here, where Q > 0.1.
        let (mut term, mut sum, mut ap) = (1.0 / a, 1.0 / a, a);
        while term.abs() > sum.abs() * 1e-17 {
            ap += 1.0;
            term *= z / ap;
            sum += term;
        }
        1.0 - front * sum
    } else {
        // Lentz continued fraction for Q(a, z).
        const TINY: f64 = 1e-300;
        let guard = |v: f64| if v.abs() < TINY { TINY } else { v };
        let mut b = z + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = 1.0 / guard(an * d + b);
            c = guard(b + an / c);
            let del = d * c;
            h *= del;
            if (del - 1.0).abs() < 1e-16 {
                break;
            }
        }
        front * h
    }
}
