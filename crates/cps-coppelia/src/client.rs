//! The ZMQ remote-API client (protocol v2, CoppeliaSim 4.6+; v1 servers, CoppeliaSim
//! 4.3–4.5, are detected and spoken to in their dialect: setter argument order, and
//! stepping through the global `setStepping`/`step` calls with the step counter published
//! on the port after the request port).

use std::time::Duration;

use tokio::net::TcpStream;
use tokio::runtime::Runtime;

use crate::zmtp::{Connection, SocketType, ZmtpError};

use crate::CoppeliaError;
use crate::codec::{self, Value};

use crate::config::{ClientConfig, Protocol};

/// A connection to CoppeliaSim's ZMQ remote API (or the stand-in server). Calls are
/// blocking; every call is bounded by the configured timeout, and a socket that timed out
/// or failed is rebuilt on the next call. Dropping the client says goodbye (`_*end*_`).
pub struct Client {
    config: ClientConfig,
    runtime: Runtime,
    socket: Option<Connection<TcpStream>>,
    uuid: String,
    first: bool,
    protocol: Protocol,
    /// v1 only: the step counter's SUB socket, connected when stepping is enabled.
    step_counter: Option<StepCounter>,
    step_endpoint: Option<String>,
    callbacks: std::collections::HashMap<String, Callback>,
}

/// A function the server may call back during a request (see
/// [`Client::register_callback`]).
type Callback = Box<dyn FnMut(&[Value]) -> Vec<Value> + Send>;

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("endpoint", &self.config.endpoint)
            .field("uuid", &self.uuid)
            .field("protocol", &self.protocol)
            .finish()
    }
}

impl Client {
    /// Connects and loads the `sim` namespace (`zmqRemoteApi.require("sim")`); falls back
    /// to protocol v1 when the server does not know `require`.
    pub fn connect(config: ClientConfig) -> Result<Self, CoppeliaError> {
        if !config.endpoint.starts_with("tcp://") {
            return Err(CoppeliaError::InvalidConfig(format!(
                "endpoint `{}` must look like tcp://host:port",
                config.endpoint
            )));
        }
        for (name, t) in [
            ("connect timeout", config.connect_timeout),
            ("call timeout", config.call_timeout),
        ] {
            if !(0.001..=86_400.0).contains(&t.as_secs_f64()) {
                return Err(CoppeliaError::InvalidConfig(format!(
                    "the {name} must be between 1 ms and one day (got {t:?})"
                )));
            }
        }
        if !(64..=1 << 30).contains(&config.max_message_bytes) {
            return Err(CoppeliaError::InvalidConfig(
                "the message limit must be between 64 bytes and 1 GiB".into(),
            ));
        }
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| {
                CoppeliaError::InvalidConfig(format!("cannot start the I/O runtime: {e}"))
            })?;
        let mut client = Self {
            config,
            runtime,
            socket: None,
            uuid: uuid::Uuid::new_v4().to_string(),
            first: true,
            protocol: Protocol::V2,
            step_counter: None,
            step_endpoint: None,
            callbacks: std::collections::HashMap::new(),
        };
        match client.call_with("zmqRemoteApi.require", vec![codec::text("sim")], true) {
            Ok(_) => {}
            Err(CoppeliaError::Remote { message, .. }) if message.contains("No such function") => {
                client.protocol = Protocol::V1;
            }
            Err(e) => return Err(e),
        }
        Ok(client)
    }

    /// The dialect in use.
    pub fn protocol(&self) -> Protocol {
        self.protocol
    }

    /// The endpoint.
    pub fn endpoint(&self) -> &str {
        &self.config.endpoint
    }

    /// The time allowed for each call.
    pub fn call_timeout(&self) -> Duration {
        self.config.call_timeout
    }

    /// Registers `f` as a callback named `name` and returns the argument to pass where a
    /// `sim` function expects a function (`"<name>@func"` on the wire). While a call is in
    /// progress the server may call it, any number of times, with its arguments; what it
    /// returns goes back to the server. An unregistered callback is answered with nothing.
    pub fn register_callback(
        &mut self,
        name: &str,
        f: impl FnMut(&[Value]) -> Vec<Value> + Send + 'static,
    ) -> Value {
        self.callbacks.insert(name.to_string(), Box::new(f));
        codec::text(&format!("{name}@func"))
    }

    /// Protocol v1 only: where the server publishes its step counter (CoppeliaSim's
    /// `zmqRemoteApi.cntPort`). Default: the request port + 1 on the same host.
    pub fn set_step_counter_endpoint(&mut self, endpoint: &str) {
        self.step_endpoint = Some(endpoint.to_string());
        self.step_counter = None;
    }

    fn step_counter_endpoint(&self) -> Result<String, CoppeliaError> {
        if let Some(e) = &self.step_endpoint {
            return Ok(e.clone());
        }
        let ep = &self.config.endpoint;
        let (host, port) = ep
            .rsplit_once(':')
            .and_then(|(h, p)| p.parse::<u16>().ok().map(|p| (h, p)))
            .ok_or_else(|| {
                CoppeliaError::InvalidConfig(format!(
                    "cannot derive the step counter's port from `{ep}`: set it with set_step_counter_endpoint"
                ))
            })?;
        Ok(format!("{host}:{}", port.wrapping_add(1)))
    }

    /// v1 stepping on or off: the global `setStepping [enable, uuid]`; turning it on
    /// connects the step counter's SUB socket first.
    pub(crate) fn v1_set_stepping(&mut self, enabled: bool) -> Result<i64, CoppeliaError> {
        if enabled && self.step_counter.is_none() {
            let endpoint = self.step_counter_endpoint()?;
            let timeout = self.config.connect_timeout;
            let max = self.config.max_message_bytes;
            let result = self.runtime.block_on(async {
                tokio::time::timeout(timeout, async {
                    let mut sub = open(&endpoint, SocketType::Sub, max).await?;
                    sub.subscribe_all().await.map_err(|e| e.to_string())?;
                    Ok::<_, String>(sub)
                })
                .await
            });
            self.step_counter = Some(match result {
                Ok(Ok(sub)) => StepCounter::spawn(&self.runtime, sub),
                Ok(Err(message)) => {
                    return Err(CoppeliaError::Connection {
                        endpoint,
                        function: "setStepping (step counter)".into(),
                        message,
                    });
                }
                Err(_) => {
                    return Err(CoppeliaError::Timeout {
                        endpoint,
                        function: "setStepping (step counter)".into(),
                        timeout_ms: timeout.as_millis() as u64,
                    });
                }
            });
        }
        let uuid = codec::text(&self.uuid);
        let ret = self.call("setStepping", vec![Value::Bool(enabled), uuid])?;
        Ok(ret.first().and_then(codec::as_i64).unwrap_or(0))
    }

    /// One v1 step: drain old counter messages, `step [uuid]`, then wait (within the call
    /// timeout) for the counter the server publishes after the step.
    pub(crate) fn v1_step(&mut self) -> Result<(), CoppeliaError> {
        if self.step_counter.is_none() {
            self.v1_set_stepping(true)?;
        }
        let mut sub = self.step_counter.take().expect("connected above");
        self.runtime.block_on(async {
            // Let the reader take what is buffered, then forget old counters.
            for _ in 0..4 {
                tokio::task::yield_now().await;
            }
            while sub.rx.try_recv().is_ok() {}
        });
        let uuid = codec::text(&self.uuid);
        if let Err(e) = self.call("step", vec![uuid]) {
            self.step_counter = Some(sub);
            return Err(e);
        }
        let timeout = self.config.call_timeout;
        let got = self
            .runtime
            .block_on(async { tokio::time::timeout(timeout, sub.rx.recv()).await });
        match got {
            Ok(Some(Ok(()))) => {
                self.step_counter = Some(sub);
                Ok(())
            }
            Ok(Some(Err(message))) => Err(CoppeliaError::Connection {
                endpoint: self.step_counter_endpoint()?,
                function: "step (step counter)".into(),
                message,
            }),
            Ok(None) => Err(CoppeliaError::Connection {
                endpoint: self.step_counter_endpoint()?,
                function: "step (step counter)".into(),
                message: "the step counter's connection closed".into(),
            }),
            Err(_) => Err(CoppeliaError::Timeout {
                endpoint: self.step_counter_endpoint()?,
                function: "step (waiting for the step counter)".into(),
                timeout_ms: timeout.as_millis() as u64,
            }),
        }
    }

    fn err(
        &self,
        function: &str,
        kind: fn(String, String, String) -> CoppeliaError,
        message: String,
    ) -> CoppeliaError {
        kind(self.config.endpoint.clone(), function.to_string(), message)
    }

    /// Calls `func` with `args` and returns its return values.
    pub fn call(&mut self, func: &str, args: Vec<Value>) -> Result<Vec<Value>, CoppeliaError> {
        self.call_with(func, args, false)
    }

    fn request(&mut self, func: &str, args: &[Value]) -> Value {
        let mut entries = vec![
            ("func", codec::text(func)),
            ("args", Value::Array(args.to_vec())),
        ];
        if self.protocol == Protocol::V2 {
            entries.push(("argsL", codec::int(args.len() as i64)));
            entries.push(("uuid", codec::text(&self.uuid)));
            if self.first {
                entries.push(("ver", codec::int(2)));
                entries.push(("lang", codec::text("rust")));
                entries.push(("timeout", codec::int(600)));
            }
        }
        codec::map(entries)
    }

    /// One request/reply exchange within the deadline; on any failure the socket is
    /// dropped so the next call starts afresh.
    fn exchange(
        &mut self,
        func: &str,
        message: Value,
        timeout: Duration,
    ) -> Result<Value, CoppeliaError> {
        let endpoint = self.config.endpoint.clone();
        let max = self.config.max_message_bytes;
        let bytes = codec::encode(&message);
        let mut socket = self.socket.take();
        let result = self.runtime.block_on(async {
            tokio::time::timeout(timeout, async {
                if socket.is_none() {
                    socket = Some(open(&endpoint, SocketType::Req, max).await?);
                }
                let s = socket.as_mut().expect("socket just made");
                s.request(&bytes).await.map_err(|e| e.to_string())
            })
            .await
        });
        match result {
            Ok(Ok(payload)) => {
                self.socket = socket;
                codec::decode(&payload).map_err(|m| {
                    self.err(
                        func,
                        |e, f, m| CoppeliaError::Protocol {
                            endpoint: e,
                            function: f,
                            message: m,
                        },
                        m,
                    )
                })
            }
            Ok(Err(message)) => Err(self.err(
                func,
                |e, f, m| CoppeliaError::Connection {
                    endpoint: e,
                    function: f,
                    message: m,
                },
                message,
            )),
            Err(_) => Err(CoppeliaError::Timeout {
                endpoint: self.config.endpoint.clone(),
                function: func.into(),
                timeout_ms: timeout.as_millis() as u64,
            }),
        }
    }

    fn call_with(
        &mut self,
        func: &str,
        args: Vec<Value>,
        connecting: bool,
    ) -> Result<Vec<Value>, CoppeliaError> {
        // Connecting (a new socket) is bounded by the connect timeout, calls by the call one.
        let timeout = if connecting || self.socket.is_none() {
            self.config.connect_timeout
        } else {
            self.config.call_timeout
        };
        let deadline = std::time::Instant::now() + self.config.call_timeout.max(timeout);
        let original = self.request(func, &args);
        let mut message = original.clone();
        self.first = false;
        loop {
            let left = deadline.saturating_duration_since(std::time::Instant::now());
            if left.is_zero() {
                self.socket = None;
                return Err(CoppeliaError::Timeout {
                    endpoint: self.config.endpoint.clone(),
                    function: func.into(),
                    timeout_ms: self.config.call_timeout.as_millis() as u64,
                });
            }
            let reply = self.exchange(func, message.clone(), left.min(timeout))?;
            let protocol = |m: String| CoppeliaError::Protocol {
                endpoint: self.config.endpoint.clone(),
                function: func.into(),
                message: m,
            };
            if !matches!(codec::untag(&reply), Value::Map(_)) {
                return Err(protocol(format!(
                    "the reply is {}, not a map",
                    codec::describe(&reply)
                )));
            }
            if let Some(f) = codec::get(&reply, "func") {
                let f = codec::as_text(f).ok_or_else(|| protocol("`func` is not text".into()))?;
                message = match f.as_str() {
                    "_*repeat*_" => original.clone(),
                    name => match self.callbacks.get_mut(name) {
                        // A registered callback: call it, answer with its results.
                        Some(cb) => {
                            let args =
                                codec::as_list(codec::get(&reply, "args")).unwrap_or_default();
                            let results = cb(&args);
                            self.request("_*executed*_", &results)
                        }
                        // `_*wait*_` and unregistered callbacks: answer "executed".
                        None => self.request("_*executed*_", &[]),
                    },
                };
                continue;
            }
            if let Some(e) = codec::get(&reply, "err") {
                let text = codec::as_text(e).unwrap_or_else(|| "an error that is not text".into());
                return Err(CoppeliaError::Remote {
                    endpoint: self.config.endpoint.clone(),
                    function: func.into(),
                    message: text.replace("_=NL=_", "\n").replace("_=TB=_", "\t"),
                });
            }
            if codec::get(&reply, "success").and_then(codec::as_bool) == Some(false) {
                let text = codec::get(&reply, "error")
                    .and_then(codec::as_text)
                    .unwrap_or_else(|| "unknown error".into());
                return Err(CoppeliaError::Remote {
                    endpoint: self.config.endpoint.clone(),
                    function: func.into(),
                    message: text,
                });
            }
            return codec::as_list(codec::get(&reply, "ret"))
                .ok_or_else(|| protocol("the reply's `ret` is neither a list nor empty".into()));
        }
    }
}

/// Protocol v1's step counter: a task reads the SUB connection and signals each message
/// (reads are never cancelled half-way, so framing survives timeouts).
struct StepCounter {
    rx: tokio::sync::mpsc::Receiver<Result<(), String>>,
    task: tokio::task::JoinHandle<()>,
}

impl StepCounter {
    fn spawn(runtime: &Runtime, mut sub: Connection<TcpStream>) -> Self {
        let (tx, rx) = tokio::sync::mpsc::channel(64);
        let task = runtime.spawn(async move {
            loop {
                match sub.recv().await {
                    Ok(_) => {
                        // A full queue already says "a step happened".
                        let _ = tx.try_send(Ok(()));
                    }
                    Err(e) => {
                        let _ = tx.send(Err(e.to_string())).await;
                        return;
                    }
                }
            }
        });
        Self { rx, task }
    }
}

impl Drop for StepCounter {
    fn drop(&mut self) {
        self.task.abort();
    }
}

/// Connects a TCP stream to `tcp://host:port` and shakes hands as `kind`.
async fn open(
    endpoint: &str,
    kind: SocketType,
    max: usize,
) -> Result<Connection<TcpStream>, String> {
    let address = endpoint.trim_start_matches("tcp://");
    let stream = TcpStream::connect(address)
        .await
        .map_err(|e| e.to_string())?;
    let _ = stream.set_nodelay(true);
    Connection::handshake(stream, kind, max)
        .await
        .map_err(|e: ZmtpError| e.to_string())
}

impl Drop for Client {
    fn drop(&mut self) {
        if self.socket.is_some() && self.protocol == Protocol::V2 {
            let bye = self.request("_*end*_", &[]);
            let _ = self.exchange("_*end*_", bye, Duration::from_millis(500));
        }
    }
}
