//! The simulated camera on the network: GigE Vision discovery and control (GVCP) and its image
//! stream (GVSP), answered on an address of the camera's own over aravis's fake-camera
//! registers (`ArvFakeCamera`: the bootstrap and feature registers, frame timing and the frame
//! fill).
//!
//! GigE Vision fixes the control port (3956), so two cameras on one host need two addresses.
//! aravis's own GigE fake camera answers on an interface's first address only (on loopback
//! 127.0.0.1, whichever camera bound it first); this peer takes the first loopback address no
//! other program holds (Linux delivers all of 127.0.0.0/8 to `lo`; binding the control port is
//! the claim, so two cameras starting at once cannot take the same one). Discovery broadcasts
//! reach every camera on the host through a socket each shares on 255.255.255.255:3956.
//!
//! The control channel privilege behaves as a GigE Vision 2.0 camera's: the application that
//! writes the control bit of `CCP` (0x0A00) first holds it until it writes 0 or its heartbeat
//! lapses (`HeartbeatTimeout`, 0x0938); meanwhile another application's writes are answered
//! `ACCESS_DENIED` and the holder's address and port stand in the primary application
//! registers (0x0A14, 0x0A10), where a client can read who holds the camera.

use crate::gigevision::{bootstrap, GVCP_PORT};
use crate::{Error, Result};
use aravis_sys as ffi;
use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// Bytes of register memory the fake camera backs; its GenICam description follows them (the
/// bootstrap's URL says `Local:...;10000;SIZE`).
const MEMORY_SIZE: u32 = 0x10000;
/// Largest data block of one GVCP read or write (bytes).
const GVCP_DATA_MAX: u32 = 512;
/// IP, UDP and GVSP headers of a stream packet (bytes).
const GVSP_OVERHEAD: usize = 20 + 8 + 8;

/// GVCP commands and their acknowledges (the acknowledge is the command + 1).
mod command {
    pub const DISCOVERY: u16 = 0x0002;
    pub const PACKET_RESEND: u16 = 0x0040;
    pub const READ_REGISTER: u16 = 0x0080;
    pub const WRITE_REGISTER: u16 = 0x0082;
    pub const READ_MEMORY: u16 = 0x0084;
    pub const WRITE_MEMORY: u16 = 0x0086;
}

/// GVCP status codes (GigE Vision 2.0, table 19-1).
mod status {
    pub const SUCCESS: u16 = 0x0000;
    pub const NOT_IMPLEMENTED: u16 = 0x8001;
    pub const INVALID_PARAMETER: u16 = 0x8002;
    pub const BAD_ALIGNMENT: u16 = 0x8005;
    pub const ACCESS_DENIED: u16 = 0x8006;
    pub const INVALID_ADDRESS: u16 = 0x800b;
}

/// The sockets of one simulated camera, bound: its address is claimed while they live.
pub struct Endpoint {
    /// Where it answers.
    pub address: Ipv4Addr,
    control: UdpSocket,
    discovery: Option<UdpSocket>,
    stream: UdpSocket,
}

impl Endpoint {
    /// Bind the camera's sockets on `interface`: `lo` (or `loopback`) for the first free
    /// loopback address, an IPv4 address for exactly that one, or another interface's name for
    /// its IPv4 address.
    pub fn bind(interface: &str) -> Result<Self> {
        if matches!(interface, "lo" | "loopback") {
            let taken = |e: &std::io::Error| e.kind() == std::io::ErrorKind::AddrInUse;
            for host in 1..=254u8 {
                let address = Ipv4Addr::new(127, 0, 0, host);
                match Self::bind_at(address) {
                    Err(BindError::Control(e)) if taken(&e) => continue,
                    other => return other.map_err(|e| e.into_error(address)),
                }
            }
            return Err(Error::camera(
                "simulated camera",
                "every loopback address from 127.0.0.1 to 127.0.0.254 has its GigE Vision control port \
                 (3956) taken: stop some of the simulated cameras running on this host",
            ));
        }
        let address = match interface.parse::<Ipv4Addr>() {
            Ok(address) => address,
            Err(_) => interface_address(interface)?,
        };
        Self::bind_at(address).map_err(|e| e.into_error(address))
    }

    fn bind_at(address: Ipv4Addr) -> std::result::Result<Self, BindError> {
        let control = UdpSocket::bind((address, GVCP_PORT)).map_err(BindError::Control)?;
        let stream = UdpSocket::bind((address, 0)).map_err(BindError::Other)?;
        // Never fragmented, as a camera's stream with SCPS's do-not-fragment flag: a packet
        // larger than the path's MTU is refused, not split.
        let discover: libc::c_int = libc::IP_PMTUDISC_DO;
        // SAFETY: an open socket and an int option of the size given.
        let set = unsafe {
            libc::setsockopt(
                stream.as_raw_fd(),
                libc::IPPROTO_IP,
                libc::IP_MTU_DISCOVER,
                (&discover as *const libc::c_int).cast(),
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if set != 0 {
            return Err(BindError::Other(std::io::Error::last_os_error()));
        }
        // Shared with every other camera on the host (and with aravis's own fake cameras, which
        // set the same options); without it the camera is still found by its address.
        let discovery = discovery_socket().ok();
        for socket in [Some(&control), discovery.as_ref()].into_iter().flatten() {
            socket.set_nonblocking(true).map_err(BindError::Other)?;
        }
        Ok(Self { address, control, discovery, stream })
    }
}

/// Why the sockets could not be bound.
enum BindError {
    /// The control port at the address.
    Control(std::io::Error),
    /// Anything else.
    Other(std::io::Error),
}

impl BindError {
    fn into_error(self, address: Ipv4Addr) -> Error {
        let device = format!("simulated camera at {address}");
        match self {
            BindError::Control(e) if e.kind() == std::io::ErrorKind::AddrInUse => Error::camera(
                device,
                format!(
                    "{address}:{GVCP_PORT} is taken (another camera answers there); leave the interface \
                     out to take a free loopback address"
                ),
            ),
            BindError::Control(e) | BindError::Other(e) => Error::camera(device, format!("cannot bind: {e}")),
        }
    }
}

/// A UDP socket on 255.255.255.255:3956 that other sockets may share.
fn discovery_socket() -> std::io::Result<UdpSocket> {
    let socket = socket2::Socket::new(socket2::Domain::IPV4, socket2::Type::DGRAM, Some(socket2::Protocol::UDP))?;
    socket.set_reuse_address(true)?;
    socket.set_reuse_port(true)?;
    socket.bind(&SocketAddr::from((Ipv4Addr::BROADCAST, GVCP_PORT)).into())?;
    Ok(socket.into())
}

/// The IPv4 address of the network interface `name`.
fn interface_address(name: &str) -> Result<Ipv4Addr> {
    let mut list: *mut libc::ifaddrs = std::ptr::null_mut();
    // SAFETY: getifaddrs fills `list`, freed below.
    if unsafe { libc::getifaddrs(&mut list) } != 0 {
        return Err(Error::camera("simulated camera", "cannot list the network interfaces"));
    }
    let mut found = None;
    let mut names = Vec::new();
    let mut entry = list;
    while !entry.is_null() {
        // SAFETY: a node of the list getifaddrs returned.
        let node = unsafe { &*entry };
        // SAFETY: ifa_name is a NUL-terminated string.
        let node_name = unsafe { std::ffi::CStr::from_ptr(node.ifa_name) }.to_string_lossy().into_owned();
        // SAFETY: ifa_addr is null or a sockaddr whose family says its type.
        if !node.ifa_addr.is_null() && i32::from(unsafe { (*node.ifa_addr).sa_family }) == libc::AF_INET {
            // SAFETY: an AF_INET address is a sockaddr_in.
            let ip = unsafe { (*(node.ifa_addr as *const libc::sockaddr_in)).sin_addr.s_addr };
            if node_name == name && found.is_none() {
                found = Some(Ipv4Addr::from(u32::from_be(ip)));
            }
            names.push(node_name);
        }
        entry = node.ifa_next;
    }
    // SAFETY: the list getifaddrs returned.
    unsafe { libc::freeifaddrs(list) };
    found.ok_or_else(|| {
        Error::camera(
            "simulated camera",
            format!("no network interface {name:?} with an IPv4 address; interfaces: lo, {}", names.join(", ")),
        )
    })
}

/// The fake camera's register memory and frame source.
pub(super) struct Registers(pub *mut ffi::ArvFakeCamera);
// SAFETY: aravis guards the fake camera's memory and frame state; the pointer outlives every
// thread that uses it (see `SimulatedCamera`'s `Drop`).
unsafe impl Send for Registers {}
unsafe impl Sync for Registers {}

impl Registers {
    /// The register at `address` (big-endian in memory).
    pub fn read(&self, address: u32) -> u32 {
        let mut value = 0;
        // SAFETY: valid camera, address inside its memory.
        unsafe { ffi::arv_fake_camera_read_register(self.0, address, &mut value) };
        value
    }

    /// Write the register at `address`.
    pub fn write(&self, address: u32, value: u32) {
        // SAFETY: as above.
        unsafe { ffi::arv_fake_camera_write_register(self.0, address, value) };
    }

    /// Where its memory ends: the registers, then the GenICam description.
    fn end(&self) -> u32 {
        let mut size = 0usize;
        // SAFETY: valid camera; the description stays owned by it.
        unsafe { ffi::arv_fake_camera_get_genicam_xml(self.0, &mut size) };
        MEMORY_SIZE + size as u32
    }

    /// `length` bytes of memory at `address`, inside the memory (checked by the caller).
    fn read_memory(&self, address: u32, length: u32) -> Vec<u8> {
        let mut bytes = vec![0u8; length as usize];
        // SAFETY: the range lies inside the fake camera's memory.
        unsafe { ffi::arv_fake_camera_read_memory(self.0, address, length, bytes.as_mut_ptr().cast()) };
        bytes
    }

    /// Write `bytes` into memory at `address`, inside the memory (checked by the caller).
    pub fn write_memory(&self, address: u32, bytes: &[u8]) {
        let mut bytes = bytes.to_vec();
        // SAFETY: the range lies inside the fake camera's memory (aravis refuses writes past it).
        unsafe { ffi::arv_fake_camera_write_memory(self.0, address, bytes.len() as u32, bytes.as_mut_ptr().cast()) };
    }
}

/// The application holding the control channel privilege, and when it was last heard from.
struct Controller {
    address: SocketAddrV4,
    heard: Instant,
}

/// The running peer: a thread answering control packets and sending frames.
pub(super) struct Peer {
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl Peer {
    /// Announce `endpoint.address` in the camera's bootstrap registers and start answering.
    /// `lost_packet_ratio` of the stream's packets are dropped on purpose.
    pub fn start(endpoint: Endpoint, registers: Arc<Registers>, lost_packet_ratio: f64) -> Self {
        let ip = u32::from(endpoint.address);
        registers.write(bootstrap::CURRENT_IP, ip);
        registers.write(bootstrap::CURRENT_SUBNET, 0xff00_0000);
        // A locally administered MAC address made of the IP: unique among the host's cameras.
        registers.write(bootstrap::MAC_HIGH, 0x0252);
        registers.write(bootstrap::MAC_LOW, ip);
        let stop = Arc::new(AtomicBool::new(false));
        let mut server = Server {
            endpoint,
            memory_end: registers.end(),
            registers,
            controller: None,
            lost_packet_ratio: lost_packet_ratio.clamp(0.0, 1.0),
            random: 0x9e37_79b9_7f4a_7c15 ^ u64::from(ip),
            stop: stop.clone(),
        };
        let thread = std::thread::Builder::new()
            .name("simulated camera GigE Vision".into())
            .spawn(move || server.run())
            .expect("spawn a thread");
        Self { stop, thread: Some(thread) }
    }
}

impl Drop for Peer {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

struct Server {
    endpoint: Endpoint,
    registers: Arc<Registers>,
    /// End of the memory a client may read (the registers and the description).
    memory_end: u32,
    controller: Option<Controller>,
    lost_packet_ratio: f64,
    random: u64,
    stop: Arc<AtomicBool>,
}

/// A GVCP command's header fields and data.
struct Command<'a> {
    code: u16,
    id: u16,
    data: &'a [u8],
}

impl<'a> Command<'a> {
    /// The command in `packet`, or `None` for anything that is not one.
    fn parse(packet: &'a [u8]) -> Option<Self> {
        if packet.len() < 8 || packet[0] != 0x42 {
            return None;
        }
        let length = u16::from_be_bytes([packet[4], packet[5]]) as usize;
        Some(Self {
            code: u16::from_be_bytes([packet[2], packet[3]]),
            id: u16::from_be_bytes([packet[6], packet[7]]),
            data: &packet[8..(8 + length).min(packet.len())],
        })
    }

    /// The acknowledge of this command with `status` and `data`.
    fn ack(&self, status: u16, data: &[u8]) -> Vec<u8> {
        let mut packet = Vec::with_capacity(8 + data.len());
        packet.extend_from_slice(&status.to_be_bytes());
        packet.extend_from_slice(&(self.code + 1).to_be_bytes());
        packet.extend_from_slice(&(data.len() as u16).to_be_bytes());
        packet.extend_from_slice(&self.id.to_be_bytes());
        packet.extend_from_slice(data);
        packet
    }

    /// The big-endian word at `index` of the data.
    fn word(&self, index: usize) -> Option<u32> {
        self.data.get(4 * index..4 * index + 4).map(|w| u32::from_be_bytes([w[0], w[1], w[2], w[3]]))
    }
}

/// Whether `length` bytes at `address` lie before `end`.
fn inside(address: u32, length: u32, end: u32) -> bool {
    u64::from(address) + u64::from(length) <= u64::from(end)
}

impl Server {
    fn run(&mut self) {
        let mut buffer = vec![0u8; 2048];
        let mut stream: Option<Stream> = None;
        // When the next frame is due: a deadline that stays put until it is reached.
        let mut due_at: Option<Instant> = None;
        while !self.stop.load(Ordering::Relaxed) {
            let wait = due_at.map_or(Duration::from_millis(100), |t| {
                t.saturating_duration_since(Instant::now()).min(Duration::from_millis(100))
            });
            self.answer_control(&mut buffer, wait);
            let privilege = self.registers.read(bootstrap::CONTROL_CHANNEL_PRIVILEGE);
            // SAFETY: valid camera.
            let acquiring = unsafe { ffi::arv_fake_camera_get_acquisition_status(self.registers.0) } != 0;
            if privilege == 0 || !acquiring {
                (stream, due_at) = (None, None);
                continue;
            }
            let stream = stream.get_or_insert_with(|| Stream::new(&self.registers));
            if due_at.is_some_and(|t| Instant::now() < t) {
                continue;
            }
            // SAFETY: valid camera.
            let due = unsafe {
                ffi::arv_fake_camera_is_in_free_running_mode(self.registers.0) != 0
                    || (ffi::arv_fake_camera_is_in_software_trigger_mode(self.registers.0) != 0
                        && ffi::arv_fake_camera_check_and_acknowledge_software_trigger(self.registers.0) != 0)
            };
            if due {
                self.send_frame(stream);
            }
            due_at = Some(self.next_frame_time());
        }
    }

    /// When the fake camera's frame clock (frame period or trigger rate) next ticks.
    fn next_frame_time(&self) -> Instant {
        let mut next_us = 0u64;
        // SAFETY: valid camera.
        let sleep_us = unsafe { ffi::arv_fake_camera_get_sleep_time_for_next_frame(self.registers.0, &mut next_us) };
        Instant::now() + Duration::from_micros(sleep_us)
    }

    /// Answer control packets as they come for up to `wait`.
    fn answer_control(&mut self, buffer: &mut [u8], wait: Duration) {
        let sockets: Vec<&UdpSocket> =
            [Some(&self.endpoint.control), self.endpoint.discovery.as_ref()].into_iter().flatten().collect();
        let mut fds: Vec<libc::pollfd> =
            sockets.iter().map(|s| libc::pollfd { fd: s.as_raw_fd(), events: libc::POLLIN, revents: 0 }).collect();
        // Rounded up: a poll that ends before the deadline would spin until it.
        let timeout_ms = wait.as_micros().div_ceil(1000) as i32;
        // SAFETY: `fds` holds open descriptors.
        let ready = unsafe { libc::poll(fds.as_mut_ptr(), fds.len() as libc::nfds_t, timeout_ms) };
        if ready <= 0 {
            return;
        }
        let mut received = Vec::new();
        for (socket, fd) in sockets.iter().zip(&fds) {
            if fd.revents & libc::POLLIN != 0 {
                while let Ok((n, SocketAddr::V4(from))) = socket.recv_from(buffer) {
                    received.push((buffer[..n].to_vec(), from));
                }
            }
        }
        for (packet, from) in received {
            if let Some(reply) = self.handle(&packet, from) {
                // Answers leave from the camera's own address, as a camera's do.
                let _ = self.endpoint.control.send_to(&reply, from);
            }
        }
    }

    /// The answer to the control packet `packet` from `from`, if any.
    fn handle(&mut self, packet: &[u8], from: SocketAddrV4) -> Option<Vec<u8>> {
        let command = Command::parse(packet)?;
        let timeout = Duration::from_millis(u64::from(self.registers.read(bootstrap::HEARTBEAT_TIMEOUT).max(500)));
        if self.controller.as_ref().is_some_and(|c| c.heard.elapsed() > timeout) {
            self.release();
        }
        let primary = match &mut self.controller {
            Some(c) if c.address == from => {
                c.heard = Instant::now();
                true
            }
            Some(_) => false,
            None => true,
        };
        let wants_ack = command.code != command::PACKET_RESEND;
        let (status, data) = match command.code {
            command::DISCOVERY => {
                (status::SUCCESS, self.registers.read_memory(0, bootstrap::DISCOVERY_DATA_SIZE as u32))
            }
            command::READ_REGISTER => self.read_registers(&command),
            command::WRITE_REGISTER if !primary => (status::ACCESS_DENIED, vec![0; 4]),
            command::WRITE_REGISTER => self.write_registers(&command, from),
            command::READ_MEMORY => match (command.word(0), command.word(1).map(|w| w & 0xffff)) {
                // A read may run past the description's end (clients read whole words and
                // blocks): the rest reads as zeros.
                (Some(address), Some(length)) if length <= GVCP_DATA_MAX && address < self.memory_end => {
                    let mut data = address.to_be_bytes().to_vec();
                    data.extend(self.registers.read_memory(address, length));
                    (status::SUCCESS, data)
                }
                (Some(address), Some(_)) => (status::INVALID_ADDRESS, address.to_be_bytes().to_vec()),
                _ => (status::INVALID_PARAMETER, vec![0; 4]),
            },
            command::WRITE_MEMORY if !primary => (status::ACCESS_DENIED, vec![0; 4]),
            command::WRITE_MEMORY => match command.word(0) {
                // aravis refuses a write that reaches the end of its memory.
                Some(address) if inside(address, command.data.len() as u32 - 4, self.memory_end - 1) => {
                    self.registers.write_memory(address, &command.data[4..]);
                    (status::SUCCESS, ((command.data.len() - 4) as u32).to_be_bytes().to_vec())
                }
                Some(_) => (status::INVALID_ADDRESS, vec![0; 4]),
                None => (status::INVALID_PARAMETER, vec![0; 4]),
            },
            // The simulated link loses only what it drops on purpose: nothing to resend.
            command::PACKET_RESEND => (status::SUCCESS, Vec::new()),
            _ => (status::NOT_IMPLEMENTED, Vec::new()),
        };
        wants_ack.then(|| command.ack(status, &data))
    }

    fn read_registers(&mut self, command: &Command) -> (u16, Vec<u8>) {
        let count = command.data.len() / 4;
        let mut values = Vec::with_capacity(4 * count);
        for k in 0..count {
            let address = command.word(k).expect("within the data");
            if !address.is_multiple_of(4) {
                return (status::BAD_ALIGNMENT, values);
            }
            if !inside(address, 4, MEMORY_SIZE) {
                return (status::INVALID_ADDRESS, values);
            }
            values.extend(self.registers.read(address).to_be_bytes());
        }
        (status::SUCCESS, values)
    }

    fn write_registers(&mut self, command: &Command, from: SocketAddrV4) -> (u16, Vec<u8>) {
        let count = command.data.len() / 8;
        for k in 0..count {
            let (address, value) = (command.word(2 * k).expect("data"), command.word(2 * k + 1).expect("data"));
            let status = if !address.is_multiple_of(4) {
                status::BAD_ALIGNMENT
            } else if !inside(address, 4, MEMORY_SIZE) {
                status::INVALID_ADDRESS
            } else {
                status::SUCCESS
            };
            if status != status::SUCCESS {
                return (status, (k as u32).to_be_bytes().to_vec());
            }
            if address == bootstrap::STREAM_CHANNEL_PACKET_SIZE && value & bootstrap::FIRE_TEST_PACKET != 0 {
                self.registers.write(address, value & !bootstrap::FIRE_TEST_PACKET);
                self.send_test_packet(value & 0xffff);
                continue;
            }
            self.registers.write(address, value);
            if address == bootstrap::CONTROL_CHANNEL_PRIVILEGE {
                if value & (bootstrap::PRIVILEGE_CONTROL | bootstrap::PRIVILEGE_EXCLUSIVE) == 0 {
                    self.release();
                } else {
                    self.controller = Some(Controller { address: from, heard: Instant::now() });
                    self.registers.write(bootstrap::PRIMARY_APPLICATION_IP, u32::from(*from.ip()));
                    self.registers.write(bootstrap::PRIMARY_APPLICATION_PORT, u32::from(from.port()));
                }
            }
        }
        (status::SUCCESS, (count as u32).to_be_bytes().to_vec())
    }

    /// A test packet of `packet_size` bytes (IP and UDP headers included) to the stream's
    /// destination; too large for the path, it is not sent (the stream socket does not
    /// fragment), which is how a client finds the largest packet size that works.
    fn send_test_packet(&self, packet_size: u32) {
        let mut packet = vec![0u8; (packet_size as usize).saturating_sub(20 + 8).max(8)];
        packet[4] = 4 << 4; // GVSP's test-packet format in the header's format field
        let _ = self.endpoint.stream.send_to(&packet, Stream::destination(&self.registers));
    }

    /// The control channel is free again.
    fn release(&mut self) {
        self.controller = None;
        for address in [
            bootstrap::CONTROL_CHANNEL_PRIVILEGE,
            bootstrap::PRIMARY_APPLICATION_IP,
            bootstrap::PRIMARY_APPLICATION_PORT,
        ] {
            self.registers.write(address, 0);
        }
    }

    /// A uniform number in [0, 1) (xorshift64*).
    fn uniform(&mut self) -> f64 {
        self.random ^= self.random >> 12;
        self.random ^= self.random << 25;
        self.random ^= self.random >> 27;
        (self.random.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }

    /// Fill a frame and send it: leader, payload packets, trailer.
    fn send_frame(&mut self, stream: &mut Stream) {
        let mut packet_size = 0u32;
        // SAFETY: valid camera and buffer of the camera's payload.
        unsafe { ffi::arv_fake_camera_fill_buffer(self.registers.0, stream.buffer, &mut packet_size) };
        // The size aravis reports is what a stream received (0 here): the frame fills the
        // buffer's allocated payload.
        let mut received = 0usize;
        // SAFETY: the buffer's data block.
        let data = unsafe { ffi::arv_buffer_get_data(stream.buffer, &mut received) };
        if data.is_null() {
            return;
        }
        // SAFETY: the buffer was allocated with `stream.payload` bytes and lives in `stream`.
        let payload = unsafe { std::slice::from_raw_parts(data.cast_const(), stream.payload) };
        let buffer = stream.buffer;
        // SAFETY: valid buffer filled above.
        let (frame_id, timestamp, format, width, height, x, y) = unsafe {
            (
                ffi::arv_buffer_get_frame_id(buffer) as u16,
                ffi::arv_buffer_get_timestamp(buffer),
                ffi::arv_buffer_get_image_pixel_format(buffer),
                ffi::arv_buffer_get_image_width(buffer) as u32,
                ffi::arv_buffer_get_image_height(buffer) as u32,
                ffi::arv_buffer_get_image_x(buffer) as u32,
                ffi::arv_buffer_get_image_y(buffer) as u32,
            )
        };
        let mut leader = Vec::with_capacity(36);
        leader.extend_from_slice(&0u16.to_be_bytes()); // flags
        leader.extend_from_slice(&1u16.to_be_bytes()); // payload type: image
        leader.extend_from_slice(&((timestamp >> 32) as u32).to_be_bytes());
        leader.extend_from_slice(&(timestamp as u32).to_be_bytes());
        for word in [format, width, height, x, y] {
            leader.extend_from_slice(&word.to_be_bytes());
        }
        leader.extend_from_slice(&[0; 4]); // padding x, y
        let chunk = (packet_size as usize).saturating_sub(GVSP_OVERHEAD).max(64);
        let mut packet_id = 0u32;
        self.send_packet(stream, frame_id, Content::Leader, packet_id, &leader);
        for block in payload.chunks(chunk) {
            packet_id += 1;
            self.send_packet(stream, frame_id, Content::Payload, packet_id, block);
        }
        let mut trailer = 1u32.to_be_bytes().to_vec();
        trailer.extend_from_slice(&height.to_be_bytes());
        self.send_packet(stream, frame_id, Content::Trailer, packet_id + 1, &trailer);
    }

    fn send_packet(&mut self, stream: &mut Stream, frame_id: u16, content: Content, packet_id: u32, data: &[u8]) {
        if self.lost_packet_ratio > 0.0 && self.uniform() < self.lost_packet_ratio {
            return;
        }
        let packet = &mut stream.packet;
        packet.clear();
        packet.extend_from_slice(&0u16.to_be_bytes()); // status
        packet.extend_from_slice(&frame_id.to_be_bytes());
        packet.extend_from_slice(&(((content as u32) << 24) | (packet_id & 0x00ff_ffff)).to_be_bytes());
        packet.extend_from_slice(data);
        let _ = self.endpoint.stream.send_to(packet, stream.destination);
    }
}

/// GVSP packet contents.
#[derive(Clone, Copy)]
enum Content {
    Leader = 1,
    Trailer = 2,
    Payload = 3,
}

/// A stream in progress: where it goes and the frame buffer of its payload.
struct Stream {
    destination: SocketAddrV4,
    buffer: *mut ffi::ArvBuffer,
    payload: usize,
    packet: Vec<u8>,
}

impl Stream {
    /// Where the stream channel sends.
    fn destination(registers: &Registers) -> SocketAddrV4 {
        SocketAddrV4::new(
            Ipv4Addr::from(registers.read(bootstrap::STREAM_CHANNEL_DESTINATION)),
            registers.read(bootstrap::STREAM_CHANNEL_PORT) as u16,
        )
    }

    fn new(registers: &Registers) -> Self {
        let destination = Self::destination(registers);
        // SAFETY: valid camera.
        let payload = unsafe { ffi::arv_fake_camera_get_payload(registers.0) };
        // SAFETY: a new buffer of `payload` bytes that aravis allocates; freed in `Drop`.
        let buffer = unsafe { ffi::arv_buffer_new(payload, std::ptr::null_mut()) };
        Self { destination, buffer, payload, packet: Vec::with_capacity(9000) }
    }
}

impl Drop for Stream {
    fn drop(&mut self) {
        // SAFETY: the buffer made in `new`, used by nothing else.
        unsafe { aravis::glib::gobject_ffi::g_object_unref(self.buffer.cast()) };
    }
}
