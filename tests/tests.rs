mod link_replay;
mod modbus_peer;
mod signal;
