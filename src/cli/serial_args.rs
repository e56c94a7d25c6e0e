//! Serial line options shared by the subcommands that talk to a controller.

use std::time::Duration;

use servosight::link::{ModbusConfig, Parity};

/// How to reach the controller.
#[derive(Debug, Clone, clap::Args)]
pub struct SerialArgs {
    /// Serial device of the controller (e.g. /dev/ttyUSB0, or one end of a socat pty pair).
    #[arg(long)]
    pub port: String,
    /// Line settings.
    #[command(flatten)]
    pub line: SerialLineArgs,
}

/// The serial line and polling settings, shared by every command that may talk to a
/// controller (the HMI takes them with an optional `--port`).
#[derive(Debug, Clone, clap::Args)]
pub struct SerialLineArgs {
    /// Baud rate.
    #[arg(long, default_value_t = 115_200)]
    pub baud: u32,
    /// Parity: none, even or odd.
    #[arg(long, default_value = "none")]
    pub parity: Parity,
    /// Stop bits (1 or 2).
    #[arg(long, default_value_t = 1)]
    pub stop_bits: u8,
    /// Modbus slave id of the controller.
    #[arg(long, default_value_t = 1)]
    pub slave: u8,
    /// Polls of the sample block per second.
    #[arg(long, default_value_t = 50.0)]
    pub poll_hz: f64,
    /// Reply timeout, ms.
    #[arg(long, default_value_t = 200)]
    pub timeout_ms: u64,
}

impl SerialArgs {
    /// The link configuration.
    pub fn config(&self) -> ModbusConfig {
        self.line.config(&self.port)
    }
}

impl SerialLineArgs {
    /// The link configuration for the controller on `port`.
    pub fn config(&self, port: &str) -> ModbusConfig {
        let mut config = ModbusConfig::new(port);
        config.baud = self.baud;
        config.parity = self.parity;
        config.stop_bits = self.stop_bits;
        config.slave = self.slave;
        config.poll_hz = self.poll_hz;
        config.request_timeout = Duration::from_millis(self.timeout_ms);
        config
    }
}
