//! The studio's HTTP server: the embedded page and `POST /api/viapoint`, on a runtime
//! thread of its own.

use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread::JoinHandle;

use axum::Router;
use axum::body::{Body, to_bytes};
use axum::extract::{DefaultBodyLimit, State};
use axum::http::{StatusCode, header};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use tokio::sync::{Semaphore, oneshot};

use crate::api;
use crate::assets;

use crate::config::{StudioConfig, StudioError};

#[derive(Clone)]
struct Shared {
    max_body: usize,
    max_upload: usize,
    workers: Arc<Semaphore>,
    robot: Option<Arc<crate::robot::StudioRobot>>,
    initial: Option<Arc<crate::files::OpenedTask>>,
}

/// A running studio; dropping it stops the server.
#[derive(Debug)]
pub struct StudioServer {
    url: String,
    stop: Option<oneshot::Sender<()>>,
    thread: Option<JoinHandle<()>>,
}

impl StudioServer {
    /// Binds and starts serving on a thread of its own.
    pub fn start(config: StudioConfig) -> Result<Self, StudioError> {
        if config.workers == 0 || config.workers > 1024 {
            return Err(StudioError::Config(format!(
                "workers must be between 1 and 1024 (got {})",
                config.workers
            )));
        }
        for (name, v) in [
            ("max_body_bytes", config.max_body_bytes),
            ("max_upload_bytes", config.max_upload_bytes),
        ] {
            if !(1024..=64 << 20).contains(&v) {
                return Err(StudioError::Config(format!(
                    "{name} must be between 1024 and 67108864 (got {v})"
                )));
            }
        }
        let bind_error = |message: String| StudioError::Bind {
            bind: config.bind.clone(),
            message,
        };
        let addr: SocketAddr = config
            .bind
            .parse()
            .map_err(|e| bind_error(format!("not an address host:port ({e})")))?;
        let std_listener =
            std::net::TcpListener::bind(addr).map_err(|e| bind_error(e.to_string()))?;
        std_listener
            .set_nonblocking(true)
            .map_err(|e| bind_error(e.to_string()))?;
        let local = std_listener
            .local_addr()
            .map_err(|e| bind_error(e.to_string()))?;
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| bind_error(e.to_string()))?;
        let shared = Shared {
            max_body: config.max_body_bytes,
            max_upload: config.max_upload_bytes,
            workers: Arc::new(Semaphore::new(config.workers)),
            robot: config.robot.map(Arc::new),
            initial: config.initial.map(Arc::new),
        };
        let (stop, stopped) = oneshot::channel::<()>();
        let thread = std::thread::Builder::new()
            .name("cps-studio".into())
            .spawn(move || {
                runtime.block_on(async move {
                    let Ok(listener) = tokio::net::TcpListener::from_std(std_listener) else {
                        return;
                    };
                    let _ = axum::serve(listener, router(shared))
                        .with_graceful_shutdown(async {
                            let _ = stopped.await;
                        })
                        .await;
                });
            })
            .map_err(|e| bind_error(e.to_string()))?;
        Ok(Self {
            url: format!("http://{local}"),
            stop: Some(stop),
            thread: Some(thread),
        })
    }

    /// `http://host:port` of the studio.
    pub fn url(&self) -> &str {
        &self.url
    }

    /// Blocks until the server ends (it ends when stopped from another thread or
    /// dropped).
    pub fn wait(mut self) {
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }

    /// Stops serving (open connections finish their request).
    pub fn stop(&mut self) {
        if let Some(s) = self.stop.take() {
            let _ = s.send(());
        }
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for StudioServer {
    fn drop(&mut self) {
        self.stop();
    }
}

fn router(shared: Shared) -> Router {
    Router::new()
        .route("/", get(|| async { asset("index.html") }))
        .route("/app.js", get(|| async { asset("app.js") }))
        .route("/scene.js", get(|| async { asset("scene.js") }))
        .route("/api/viapoint", post(viapoint))
        .route("/api/robot", get(robot))
        .route("/api/initial", get(initial))
        .route("/api/open", post(open))
        .route("/api/save", post(save))
        .route("/api/export", post(export))
        .route("/api/imitate", post(imitate))
        .fallback(|| async { error(StatusCode::NOT_FOUND, "no such page".into()) })
        // The body is read by the handler, within the studio's own limit.
        .layer(DefaultBodyLimit::disable())
        .with_state(shared)
}

fn asset(name: &str) -> Response {
    match assets::get(name) {
        Some((content_type, bytes)) => (
            [
                (header::CONTENT_TYPE, content_type),
                (header::CACHE_CONTROL, "no-cache"),
            ],
            bytes,
        )
            .into_response(),
        None => error(StatusCode::NOT_FOUND, "no such page".into()),
    }
}

/// An error as the page reads it: `{"error": sentence}`.
fn error(status: StatusCode, sentence: String) -> Response {
    (status, axum::Json(serde_json::json!({ "error": sentence }))).into_response()
}

/// Set when the request's future is dropped (the tab went away), so its learning stops.
struct Cancel(Arc<AtomicBool>);

impl Drop for Cancel {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// The studio's robot at rest, or 404 without one.
async fn robot(State(shared): State<Shared>) -> Response {
    match &shared.robot {
        Some(r) => axum::Json(r.view()).into_response(),
        None => error(StatusCode::NOT_FOUND, "this studio has no robot".into()),
    }
}

/// The task the studio was opened with, or 404.
async fn initial(State(shared): State<Shared>) -> Response {
    match &shared.initial {
        Some(t) => axum::Json(t.as_ref().clone()).into_response(),
        None => error(
            StatusCode::NOT_FOUND,
            "no experiment file was opened".into(),
        ),
    }
}

/// A JSON body within the studio's limit, or the 400 that says what is wrong with it.
async fn json_body<T: serde::de::DeserializeOwned>(
    shared: &Shared,
    body: Body,
) -> Result<T, Response> {
    json_within(shared.max_body, body).await
}

/// A JSON body of at most `limit` bytes.
async fn json_within<T: serde::de::DeserializeOwned>(
    limit: usize,
    body: Body,
) -> Result<T, Response> {
    let bytes = to_bytes(body, limit).await.map_err(|_| {
        error(
            StatusCode::BAD_REQUEST,
            format!("the request body is larger than {limit} bytes (or was cut off)"),
        )
    })?;
    serde_json::from_slice(&bytes)
        .map_err(|e| error(StatusCode::BAD_REQUEST, format!("invalid JSON: {e}")))
}

/// `{"name": "x.toml", "text": "..."}`: the experiment text's task, or the parser's
/// sentence (file, line, column).
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct OpenRequest {
    name: String,
    text: String,
}

async fn open(State(shared): State<Shared>, body: Body) -> Response {
    let request: OpenRequest = match json_within(shared.max_upload, body).await {
        Ok(r) => r,
        Err(e) => return e,
    };
    match crate::files::open_text(&request.name, &request.text) {
        Ok(task) => axum::Json(task).into_response(),
        Err(e) => error(StatusCode::BAD_REQUEST, e.0),
    }
}

/// `{"name": "x", "task": <a viapoint request>}`: the experiment file, as text.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SaveRequest {
    name: String,
    task: api::ViaPointRequest,
}

async fn save(State(shared): State<Shared>, body: Body) -> Response {
    let request: SaveRequest = match json_body(&shared, body).await {
        Ok(r) => r,
        Err(e) => return e,
    };
    match crate::files::save(&request.task, &request.name) {
        Ok(text) => ([(header::CONTENT_TYPE, "text/plain; charset=utf-8")], text).into_response(),
        Err(e) => error(StatusCode::BAD_REQUEST, e.0),
    }
}

/// `{"format": "ros2-yaml"|"mcap"|"csv-1khz", "task": <a viapoint request>}`: the
/// movement executed on the robot, as a file for ROS 2 and viewers.
#[derive(serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct ExportRequest {
    format: String,
    task: api::ViaPointRequest,
}

async fn export(State(shared): State<Shared>, body: Body) -> Response {
    let request: ExportRequest = match json_body(&shared, body).await {
        Ok(r) => r,
        Err(e) => return e,
    };
    if let Err(e) = request.task.config() {
        return error(StatusCode::BAD_REQUEST, e.0);
    }
    let robot = shared.robot.clone();
    let work = run_limited(&shared, move |stop| {
        api::export(&request.task, robot.as_deref(), &request.format, stop)
    })
    .await;
    match work {
        Ok((name, bytes)) => (
            [
                (header::CONTENT_TYPE, "application/octet-stream".to_string()),
                (
                    header::CONTENT_DISPOSITION,
                    format!("attachment; filename=\"{name}\""),
                ),
            ],
            bytes,
        )
            .into_response(),
        Err(r) => r,
    }
}

/// Runs learning work on the blocking pool once a worker is free (in arrival order),
/// stopped if the request goes away; a refusal as a 400.
async fn run_limited<T: Send + 'static>(
    shared: &Shared,
    work: impl FnOnce(&(dyn Fn() -> bool + Sync)) -> Result<T, api::ApiError> + Send + 'static,
) -> Result<T, Response> {
    let Ok(permit) = shared.workers.clone().acquire_owned().await else {
        return Err(error(
            StatusCode::SERVICE_UNAVAILABLE,
            "the studio is stopping".into(),
        ));
    };
    let stop = Arc::new(AtomicBool::new(false));
    let _cancel = Cancel(stop.clone());
    let done = tokio::task::spawn_blocking(move || {
        let _permit = permit;
        work(&|| stop.load(Ordering::Relaxed))
    })
    .await;
    match done {
        Ok(Ok(v)) => Ok(v),
        Ok(Err(e)) => Err(error(StatusCode::BAD_REQUEST, e.0)),
        Err(_) => Err(error(
            StatusCode::INTERNAL_SERVER_ERROR,
            "the learning run failed unexpectedly".into(),
        )),
    }
}

/// Demonstration files imitated by a DMP (and their ProMP band).
async fn imitate(State(shared): State<Shared>, body: Body) -> Response {
    let request: crate::imitation::ImitateRequest = match json_within(shared.max_upload, body).await
    {
        Ok(r) => r,
        Err(e) => return e,
    };
    match run_limited(&shared, move |_| crate::imitation::imitate(&request)).await {
        Ok(answer) => axum::Json(answer).into_response(),
        Err(r) => r,
    }
}

async fn viapoint(State(shared): State<Shared>, body: Body) -> Response {
    let request: api::ViaPointRequest = match json_body(&shared, body).await {
        Ok(r) => r,
        Err(e) => return e,
    };
    // Cheap checks before waiting for a worker.
    if let Err(e) = request.config() {
        return error(StatusCode::BAD_REQUEST, e.0);
    }
    let robot = shared.robot.clone();
    match run_limited(&shared, move |stop| {
        api::viapoint(&request, robot.as_deref(), stop)
    })
    .await
    {
        Ok(answer) => axum::Json(answer).into_response(),
        Err(r) => r,
    }
}
