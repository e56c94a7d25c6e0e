mod modbus_peer;
mod signal;
