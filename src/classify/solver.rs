//! The linear SVM solver behind `stature train` (host side, never in the
//! loop): L2-regularised, L2-loss, in the dual, by coordinate descent with
//! shrinking (Hsieh et al. 2008, "A dual coordinate descent method for
//! large-scale linear SVM"; the LIBLINEAR `-s 1` method). The bias is a
//! constant feature of value 1 (regularised like the weights, as in
//! LIBLINEAR `-B 1`). Each row has its own cost `C·weight`, so rare kinds
//! (dogs, cars) can count more than their numbers.

use super::samples::{Kind, Origin, Rng};

/// Feature rows with labels.
#[derive(Clone, Debug, Default)]
pub struct Data {
    /// Row length.
    pub dim: usize,
    /// Rows, `dim` bytes each.
    pub x: Vec<u8>,
    /// Label per row.
    pub kind: Vec<Kind>,
    /// Source per row.
    pub origin: Vec<Origin>,
    /// Cross-validation fold per row (0..5).
    pub fold: Vec<u8>,
}

impl Data {
    /// No rows of length `dim`.
    pub fn new(dim: usize) -> Self {
        Data {
            dim,
            ..Default::default()
        }
    }
    /// Appends one row.
    pub fn push(&mut self, x: &[u8], kind: Kind, origin: Origin, fold: u8) {
        self.x.extend_from_slice(x);
        self.kind.push(kind);
        self.origin.push(origin);
        self.fold.push(fold);
    }
    /// Rows.
    pub fn len(&self) -> usize {
        self.kind.len()
    }
    /// No rows.
    pub fn is_empty(&self) -> bool {
        self.kind.is_empty()
    }
    /// Row `i`.
    pub fn row(&self, i: usize) -> &[u8] {
        &self.x[i * self.dim..(i + 1) * self.dim]
    }
    /// +1 for a single person, −1 otherwise.
    pub fn label(&self, i: usize) -> f64 {
        if self.kind[i].positive() {
            1.0
        } else {
            -1.0
        }
    }
    /// Only the given columns.
    pub fn columns(&self, cols: &[usize]) -> Data {
        let mut d = Data::new(cols.len());
        d.x.reserve(self.len() * cols.len());
        for i in 0..self.len() {
            let r = self.row(i);
            d.x.extend(cols.iter().map(|&c| r[c]));
        }
        d.kind = self.kind.clone();
        d.origin = self.origin.clone();
        d.fold = self.fold.clone();
        d
    }
}

/// A trained float model: `score = Σ w_j·x_j/255 + b`.
#[derive(Clone, Debug)]
pub struct Linear {
    /// Weights per feature (features in units of 1/255).
    pub w: Vec<f32>,
    /// Bias.
    pub b: f32,
    /// Epochs run.
    pub epochs: usize,
}

impl Linear {
    /// Score of one `u8` row.
    pub fn score(&self, x: &[u8]) -> f32 {
        dot(&self.w, x) + self.b
    }
}

#[inline]
fn dot(w: &[f32], x: &[u8]) -> f32 {
    // Eight partial sums: lets the compiler vectorise without reassociation.
    let mut acc = [0f32; 8];
    let mut wc = w.chunks_exact(8);
    let mut xc = x.chunks_exact(8);
    for (a, b) in (&mut wc).zip(&mut xc) {
        for k in 0..8 {
            acc[k] += a[k] * f32::from(b[k]);
        }
    }
    let mut s: f32 = acc.iter().sum();
    for (a, b) in wc.remainder().iter().zip(xc.remainder()) {
        s += a * f32::from(*b);
    }
    s / 255.0
}

/// Cost multiplier per kind of row (1 for every kind unless set).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KindWeights(pub [f64; Kind::ALL.len()]);

impl Default for KindWeights {
    fn default() -> Self {
        KindWeights([1.0; Kind::ALL.len()])
    }
}

impl KindWeights {
    /// The multiplier of `k`.
    pub fn of(&self, k: Kind) -> f64 {
        self.0[Kind::ALL.iter().position(|&a| a == k).unwrap_or(0)]
    }

    /// Sets one multiplier from `KIND=X` (a kind name, X finite and > 0).
    pub fn set(&mut self, spec: &str) -> Result<(), String> {
        let parsed = spec.split_once('=').and_then(|(k, v)| {
            let kind = Kind::ALL.iter().position(|kind| kind.name() == k)?;
            let v: f64 = v.parse().ok().filter(|v: &f64| v.is_finite() && *v > 0.0)?;
            Some((kind, v))
        });
        let (kind, v) = parsed.ok_or_else(|| {
            format!("{spec}: expected KIND=X, KIND one of person, background, group, fragment, car, dog and X > 0")
        })?;
        self.0[kind] = v;
        Ok(())
    }
}

/// Dual coordinate descent on the rows `idx` of `d`, cost `c · weight(kind)`
/// per row. Stops when the projected-gradient spread over the whole set
/// falls below 0.1 (LIBLINEAR's default) or after 1000 passes.
pub fn solve(d: &Data, idx: &[usize], c: f64, weights: &KindWeights, seed: u64) -> Linear {
    let dim = d.dim;
    let mut w = vec![0f32; dim];
    let mut b = 0f64;
    let diag: Vec<f64> = idx
        .iter()
        .map(|&i| 0.5 / (c * weights.of(d.kind[i])))
        .collect();
    let qd: Vec<f64> = idx
        .iter()
        .zip(&diag)
        .map(|(&i, dg)| {
            let n: f64 = d
                .row(i)
                .iter()
                .map(|&v| (f64::from(v) / 255.0).powi(2))
                .sum();
            n + 1.0 + dg
        })
        .collect();
    let mut alpha = vec![0f64; idx.len()];
    // Shrinking: rows at alpha = 0 whose gradient is clearly positive leave
    // the active set; when the active set converges the whole set is
    // checked once more (LIBLINEAR's scheme).
    let mut active: Vec<usize> = (0..idx.len()).collect();
    let mut rng = Rng::new(seed);
    let mut pg_max_old = f64::INFINITY;
    let mut epochs = 0;
    while epochs < 1000 {
        epochs += 1;
        rng.shuffle(&mut active);
        let (mut pg_max, mut pg_min) = (f64::NEG_INFINITY, f64::INFINITY);
        let mut s = 0;
        while s < active.len() {
            let k = active[s];
            let i = idx[k];
            let y = d.label(i);
            let r = d.row(i);
            let g = y * (f64::from(dot(&w, r)) + b) - 1.0 + diag[k] * alpha[k];
            let pg = if alpha[k] == 0.0 {
                if g > pg_max_old {
                    active.swap_remove(s);
                    continue;
                }
                g.min(0.0)
            } else {
                g
            };
            pg_max = pg_max.max(pg);
            pg_min = pg_min.min(pg);
            if pg.abs() > 1e-12 {
                let old = alpha[k];
                alpha[k] = (old - g / qd[k]).max(0.0);
                let step = ((alpha[k] - old) * y) as f32;
                let sc = step / 255.0;
                for (wj, &xj) in w.iter_mut().zip(r) {
                    *wj += sc * f32::from(xj);
                }
                b += f64::from(step);
            }
            s += 1;
        }
        if pg_max - pg_min < 0.1 {
            if active.len() == idx.len() {
                break;
            }
            active = (0..idx.len()).collect();
            pg_max_old = f64::INFINITY;
            continue;
        }
        // No upper bound on alpha (L2 loss): only the max side shrinks.
        pg_max_old = if pg_max <= 0.0 { f64::INFINITY } else { pg_max };
    }
    Linear {
        w,
        b: b as f32,
        epochs,
    }
}

/// Share of rows `idx` that `m` gets right (threshold 0).
pub fn accuracy(m: &Linear, d: &Data, idx: &[usize]) -> f64 {
    let ok = idx
        .iter()
        .filter(|&&i| (m.score(d.row(i)) > 0.0) == d.kind[i].positive())
        .count();
    ok as f64 / idx.len().max(1) as f64
}

/// 5-fold cross-validated accuracy over the folds stored in `d`.
pub fn cross_validate(d: &Data, c: f64, weights: &KindWeights, seed: u64) -> f64 {
    let mut correct = 0.0;
    for f in 0..5u8 {
        let train: Vec<usize> = (0..d.len()).filter(|&i| d.fold[i] != f).collect();
        let test: Vec<usize> = (0..d.len()).filter(|&i| d.fold[i] == f).collect();
        let m = solve(d, &train, c, weights, seed + u64::from(f));
        correct += accuracy(&m, d, &test) * test.len() as f64;
    }
    correct / d.len() as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Two Gaussian-ish clouds in 16 dimensions: the solver must separate
    /// them, and shrinking must not change the solution it converges to.
    #[test]
    fn separates_two_clouds() {
        let mut rng = Rng::new(5);
        let mut d = Data::new(16);
        for i in 0..600 {
            let pos = i % 2 == 0;
            let row: Vec<u8> = (0..16)
                .map(|j| {
                    let centre = if pos == (j < 8) { 170.0 } else { 90.0 };
                    (centre + rng.range(-60.0, 60.0)) as u8
                })
                .collect();
            let kind = if pos { Kind::Person } else { Kind::Background };
            d.push(&row, kind, Origin::Sim, (i % 5) as u8);
        }
        let all: Vec<usize> = (0..d.len()).collect();
        let m = solve(&d, &all, 1.0, &KindWeights::default(), 1);
        assert!(accuracy(&m, &d, &all) > 0.97, "{}", accuracy(&m, &d, &all));
        assert!(cross_validate(&d, 1.0, &KindWeights::default(), 1) > 0.95);
        // Weights of the positive half point the right way.
        assert!(m.w[..8].iter().all(|&v| v > 0.0) && m.w[8..].iter().all(|&v| v < 0.0));
    }

    #[test]
    fn kind_weights_parse() {
        let mut kw = KindWeights::default();
        kw.set("dog=4").unwrap();
        assert_eq!(kw.of(Kind::Dog), 4.0);
        assert_eq!(kw.of(Kind::Person), 1.0);
        for bad in ["dog", "cat=2", "dog=0", "dog=-1", "dog=nan", "dog=x"] {
            assert!(kw.set(bad).is_err(), "{bad}");
        }
    }

    #[test]
    fn kind_weight_moves_the_boundary() {
        // Overlapping 1-D classes: weighting the negatives pushes the
        // boundary toward the positives (fewer negatives accepted).
        let mut rng = Rng::new(9);
        let mut d = Data::new(1);
        for i in 0..400 {
            let pos = i % 2 == 0;
            let v = if pos { 150.0 } else { 100.0 } + rng.range(-50.0, 50.0);
            let kind = if pos { Kind::Person } else { Kind::Dog };
            d.push(&[v as u8], kind, Origin::Sim, 0);
        }
        let all: Vec<usize> = (0..d.len()).collect();
        let accepted = |m: &Linear| {
            all.iter()
                .filter(|&&i| d.kind[i] == Kind::Dog && m.score(d.row(i)) > 0.0)
                .count()
        };
        let plain = solve(&d, &all, 1.0, &KindWeights::default(), 1);
        let mut kw = KindWeights::default();
        kw.0[Kind::ALL.iter().position(|&k| k == Kind::Dog).unwrap()] = 8.0;
        let heavy = solve(&d, &all, 1.0, &kw, 1);
        assert!(accepted(&heavy) < accepted(&plain));
    }
}
