//! Lumped-parameter thermal networks, integrated with the implicit (backward) Euler method.
//!
//! A node has a heat capacity C (J/K) and a temperature; links between nodes and from nodes to
//! fixed-temperature environments (room air, coolant) have conductances G (W/K) that may change
//! every step (convection grows with speed, coolant switches on and off). Backward Euler is
//! unconditionally stable, so a node may be massless (C = 0: it then sits at the balance of its
//! links), which is how the twin omits thermal inertia.

/// A thermal network of `N` nodes.
#[derive(Debug, Clone)]
pub struct ThermalNetwork<const N: usize> {
    capacity: [f64; N],
    temperature: [f64; N],
}

/// The conductances and heat inputs of one integration step.
#[derive(Debug, Clone)]
pub struct StepInputs<'a, const N: usize> {
    /// Node-to-node links `(i, j, G)` in W/K.
    pub links: &'a [(usize, usize, f64)],
    /// Links to environments `(i, G, T_environment)` in W/K and °C.
    pub to_environment: &'a [(usize, f64, f64)],
    /// Heat flowing into each node, W.
    pub heat: [f64; N],
}

impl<const N: usize> ThermalNetwork<N> {
    /// A network whose nodes all start at `initial` °C.
    pub fn new(capacity: [f64; N], initial: f64) -> Self {
        ThermalNetwork {
            capacity,
            temperature: [initial; N],
        }
    }

    /// Node temperatures, °C.
    pub fn temperatures(&self) -> &[f64; N] {
        &self.temperature
    }

    /// Sets every node temperature (e.g. to start from a soaked state).
    pub fn set_temperatures(&mut self, temperature: [f64; N]) {
        self.temperature = temperature;
    }

    /// Advances the network by `dt` seconds.
    ///
    /// Solves (C/dt + G) T' = C/dt T + Q + G_env T_env. The matrix is symmetric and strictly
    /// diagonally dominant whenever every node is linked (directly or not) to an environment, so
    /// elimination without pivoting is exact and stable.
    pub fn step(&mut self, dt: f64, inputs: &StepInputs<'_, N>) {
        let mut a = [[0.0_f64; N]; N];
        let mut b = [0.0_f64; N];
        for i in 0..N {
            a[i][i] = self.capacity[i] / dt;
            b[i] = self.capacity[i] / dt * self.temperature[i] + inputs.heat[i];
        }
        for &(i, j, g) in inputs.links {
            a[i][i] += g;
            a[j][j] += g;
            a[i][j] -= g;
            a[j][i] -= g;
        }
        for &(i, g, t_env) in inputs.to_environment {
            a[i][i] += g;
            b[i] += g * t_env;
        }
        // Gaussian elimination on the small dense system.
        for k in 0..N {
            let (upper, lower) = a.split_at_mut(k + 1);
            let pivot_row = &upper[k];
            let (b_upper, b_lower) = b.split_at_mut(k + 1);
            for (row, b_row) in lower.iter_mut().zip(b_lower.iter_mut()) {
                let factor = row[k] / pivot_row[k];
                if factor != 0.0 {
                    for (x, p) in row[k..].iter_mut().zip(&pivot_row[k..]) {
                        *x -= factor * p;
                    }
                    *b_row -= factor * b_upper[k];
                }
            }
        }
        // Back substitution in place: once solved, b[c] holds node c's new temperature.
        for k in (0..N).rev() {
            let mut sum = b[k];
            for c in (k + 1)..N {
                sum -= a[k][c] * b[c];
            }
            b[k] = sum / a[k][k];
        }
        self.temperature = b;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One node, constant heat Q, conductance G to a 20 °C room: T(t) = 20 + Q/G (1 − e^(−tG/C)).
    #[test]
    fn single_node_settles_at_q_over_g_with_time_constant_c_over_g() {
        let (c, g, q) = (5000.0, 2.5, 50.0);
        let mut net = ThermalNetwork::new([c], 20.0);
        let tau = c / g;
        let dt = 1.0;
        let inputs = StepInputs {
            links: &[],
            to_environment: &[(0, g, 20.0)],
            heat: [q],
        };
        let mut t = 0.0;
        while t < tau - 0.5 {
            net.step(dt, &inputs);
            t += dt;
        }
        let expected = 20.0 + q / g * (1.0 - (-1.0_f64).exp());
        let rise = net.temperatures()[0] - 20.0;
        assert!(
            (rise - (expected - 20.0)).abs() / (q / g) < 2e-3,
            "after τ: {rise} vs {}",
            expected - 20.0
        );
        for _ in 0..(20.0 * tau) as usize {
            net.step(dt, &inputs);
        }
        assert!((net.temperatures()[0] - (20.0 + q / g)).abs() < 1e-6);
    }

    /// Two nodes in series to the room: the steady state is the resistor-chain closed form.
    #[test]
    fn series_chain_steady_state_matches_resistances() {
        let mut net = ThermalNetwork::new([100.0, 0.0], 20.0);
        let inputs = StepInputs {
            links: &[(0, 1, 4.0)],
            to_environment: &[(1, 1.0, 20.0)],
            heat: [10.0, 0.0],
        };
        for _ in 0..10_000 {
            net.step(1.0, &inputs);
        }
        // 10 W through 1/4 + 1/1 K/W: node 1 at 30 °C, node 0 at 32.5 °C.
        assert!((net.temperatures()[1] - 30.0).abs() < 1e-9);
        assert!((net.temperatures()[0] - 32.5).abs() < 1e-9);
    }
}
