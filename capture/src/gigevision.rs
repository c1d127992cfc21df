//! GigE Vision's fixed protocol facts that both sides of rmvp use: the camera client (who
//! controls a camera, [`crate::camera`]) and the simulated camera's peer
//! ([`crate::simulator::gige`]).

/// The GigE Vision control port.
pub const GVCP_PORT: u16 = 3956;

/// Bootstrap registers rmvp reads (who controls a camera) or its simulated camera keeps
/// (GigE Vision 2.0, section 28), addresses in the camera's register space.
pub mod bootstrap {
    /// MAC address, high 16 bits.
    pub const MAC_HIGH: u32 = 0x0008;
    /// MAC address, low 32 bits.
    pub const MAC_LOW: u32 = 0x000c;
    /// Current IP address.
    pub const CURRENT_IP: u32 = 0x0024;
    /// Current subnet mask.
    pub const CURRENT_SUBNET: u32 = 0x0034;
    /// Size of the bootstrap block a discovery answer carries.
    pub const DISCOVERY_DATA_SIZE: usize = 0xf8;
    /// Heartbeat timeout (ms).
    pub const HEARTBEAT_TIMEOUT: u32 = 0x0938;
    /// Control channel privilege (`CCP`).
    pub const CONTROL_CHANNEL_PRIVILEGE: u32 = 0x0a00;
    /// Primary application's UDP port.
    pub const PRIMARY_APPLICATION_PORT: u32 = 0x0a10;
    /// Primary application's IP address.
    pub const PRIMARY_APPLICATION_IP: u32 = 0x0a14;
    /// `CCP`'s exclusive-access bit.
    pub const PRIVILEGE_EXCLUSIVE: u32 = 1 << 0;
    /// `CCP`'s control-access bit.
    pub const PRIVILEGE_CONTROL: u32 = 1 << 1;
    /// Stream channel 0's destination port.
    pub const STREAM_CHANNEL_PORT: u32 = 0x0d00;
    /// Stream channel 0's packet size (`SCPS`: the size in the low 16 bits).
    pub const STREAM_CHANNEL_PACKET_SIZE: u32 = 0x0d04;
    /// `SCPS`'s fire-test-packet bit.
    pub const FIRE_TEST_PACKET: u32 = 1 << 31;
    /// Stream channel 0's destination address.
    pub const STREAM_CHANNEL_DESTINATION: u32 = 0x0d18;
}
