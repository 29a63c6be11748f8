//! Flags of `chronomap serve` and `chronomap client`.

#[allow(unused_imports)]
use super::*;

pub(super) const SERVE_HELP: &str = "\
Examples:
  chronomap serve --data chronomap-data
  chronomap serve --data chronomap-data --topo witham=witham.cmt
  chronomap serve --data chronomap-data --topo lab=lab.cmt --topo-layout lab=lab.yaml
  chronomap serve --data chronomap-data --activity atc=atc.cmcopa --activity-map atc=atc_map.yaml
  chronomap serve --data chronomap-data --postgres 'host=127.0.0.1 user=robot dbname=lab'
  chronomap serve --data node1 --postgres 'host=db.lab dbname=lab' --fleet --allow-host node1.lab
  chronomap serve --data chronomap-data --bt-monitor robot=127.0.0.1:1667

  chronomap serve --data chronomap-data --check      # verify the store, exit 0 or 1
  chronomap serve --data chronomap-data --salvage    # rebuild a damaged store from what is intact

Writes (add, addvalues, observations, create, remove, refit) need `Authorization: Bearer TOKEN` and
`Content-Type: application/json`; the token is read from --token-file (default DATA/token), which
is created with a random token if it does not exist (it must be readable by its owner only and at
least 32 characters long). Reads (predict, forecast, view, ...) need no token. Requests must name
the service in `Host` by an IP address, localhost or an --allow-host name. Every acknowledged
observation is durable: a restart (also after a crash or SIGKILL) restores every model exactly.
Models fitted on a whole series (auto, fremen:auto, ...) keep their observations and are refitted
when --refit-every/--refit-secs say, or on request; each refit is logged and durable.
Security model, timeouts and limits: docs/service.md.";

/// `chronomap serve`.
#[derive(Debug, Args)]
pub struct ServeArgs {
    /// Directory of the embedded store (`chronomap.redb`) and of the default token file.
    #[arg(long)]
    pub data: PathBuf,
    /// Address to listen on (loopback by default; port 0 picks a free port).
    #[arg(long, default_value = "127.0.0.1:8470")]
    pub listen: std::net::SocketAddr,
    /// File holding the bearer token for writes (created with a random token if missing);
    /// default DATA/token.
    #[arg(long, conflicts_with = "no_token")]
    pub token_file: Option<PathBuf>,
    /// Accept writes without a token (only on a loopback --listen address of a one-user
    /// machine; refused with any other address).
    #[arg(long)]
    pub no_token: bool,
    /// A host name requests may give in `Host` besides IP addresses and `localhost` (the DNS
    /// rebinding defence refuses every other name with 421). Repeat the flag or separate
    /// them by commas.
    #[arg(long, value_delimiter = ',', value_parser = parse_host_name)]
    pub allow_host: Vec<String>,
    /// Seconds a connection may take to send a complete request head, counted from its opening
    /// or its previous answer (slow headers and idle keep-alive connections are closed).
    #[arg(long, default_value_t = 10.0, value_parser = parse_positive)]
    pub header_timeout: f64,
    /// Seconds a request body may take to arrive after its head (else 408).
    #[arg(long, default_value_t = 60.0, value_parser = parse_positive)]
    pub body_timeout: f64,
    /// Connections open at once; one more is answered 503 and closed.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=65_536))]
    pub max_connections: u32,
    /// Threads computing heavy requests (grid, activity and plan predictions, model requests of
    /// more than 16,384 predictions or 256 KiB), one request each; default half the hardware
    /// threads, at least 1.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub heavy_workers: Option<u32>,
    /// Heavy requests that may wait for a worker; one more is answered 503 with Retry-After.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(0..=65_536))]
    pub heavy_queue: u32,
    /// Threads computing light requests (smaller predict, entropy, forecast, evaluate and
    /// detect requests, grid cells, edge predictions), one request each; default half the
    /// hardware threads, at least 1.
    #[arg(long, value_parser = clap::value_parser!(u32).range(1..=1024))]
    pub light_workers: Option<u32>,
    /// Light requests that may wait for a worker; one more is answered 503 with Retry-After.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(0..=65_536))]
    pub light_queue: u32,
    /// Verify the store (every snapshot and log entry, and redb's page checksums), print a
    /// report and exit: 0 if intact, 1 if damaged. Serves nothing.
    #[arg(long, conflicts_with = "salvage")]
    pub check: bool,
    /// Rebuild a damaged store from every intact log entry, report what was lost and exit. The
    /// damaged redb file is kept as DATA/chronomap.redb.damaged-TIME; with --postgres the
    /// result goes to the schema SCHEMA_salvaged. Serves nothing.
    #[arg(long)]
    pub salvage: bool,
    /// Keep the log and snapshots in PostgreSQL instead of DATA/chronomap.redb: a libpq
    /// connection string (`host=127.0.0.1 user=robot dbname=lab`) or postgresql:// URL.
    #[arg(long)]
    pub postgres: Option<String>,
    /// PostgreSQL schema of the tables (created if missing).
    #[arg(long, default_value = "chronomap", requires = "postgres")]
    pub postgres_schema: String,
    /// Share the --postgres schema with other `chronomap serve --fleet` nodes: one log, any
    /// node answers reads and writes for every model, a read with the header
    /// `Chronomap-Read-After: SEQ` sees every write that returned `seq` ≤ SEQ on any node
    /// (docs/fleet.md). Every service on the schema must run with --fleet.
    #[arg(long, requires = "postgres", conflicts_with = "salvage")]
    pub fleet: bool,
    /// Commit groups per partition of the PostgreSQL log when the schema is created (an existing
    /// schema keeps its own). After each checkpoint, the partitions it covers move to the
    /// archive (`log_archive`), so that recovery and new nodes read only the rest.
    #[arg(long, default_value_t = 100_000, requires = "postgres",
          value_parser = clap::value_parser!(u64).range(1..=1 << 40))]
    pub postgres_segment_groups: u64,
    /// Largest request body in bytes (larger ones get 413).
    #[arg(long, default_value_t = 32 << 20)]
    pub max_body_bytes: usize,
    /// Snapshot changed models after this many observations (recovery replays fewer).
    #[arg(long, default_value_t = 1_000_000)]
    pub snapshot_every: u64,
    /// ... or after this many seconds with changes.
    #[arg(long, default_value_t = 60.0, value_parser = parse_positive)]
    pub snapshot_secs: f64,
    /// Refit a model fitted on a whole series (`auto`, `fremen:auto`, ...) once this many
    /// observations arrived since its last fit (0: not by count). `POST
    /// /v1/models/ID/refit` (`chronomap client refit ID`) refits at once.
    #[arg(long, default_value_t = 100_000)]
    pub refit_every: u64,
    /// ... or once its data advanced this many seconds past its last fit (0: not by time).
    #[arg(long, default_value_t = 86_400.0, value_parser = parse_non_negative)]
    pub refit_secs: f64,
    /// Serve a topological map with edge models (from `chronomap topo fit`) as NAME=FILE:
    /// edge predictions and now-or-later plans at /v1/topo/NAME/. Repeat the flag or separate
    /// them by commas.
    #[arg(long, value_parser = parse_named_file, value_delimiter = ',')]
    pub topo: Vec<(String, PathBuf)>,
    /// Node positions of a --topo map as NAME=FILE: a tmap2 YAML or a Nav2 route GeoJSON
    /// (.geojson, .json) placing every node.
    #[arg(long, value_parser = parse_named_file, value_delimiter = ',')]
    pub topo_layout: Vec<(String, PathBuf)>,
    /// Serve an occupancy grid file (from `chronomap grid build`) as NAME=FILE: predicted maps
    /// at /v1/grid/NAME/predict. Repeat the flag or separate them by commas.
    #[arg(long, value_parser = parse_named_file, value_delimiter = ',')]
    pub grid: Vec<(String, PathBuf)>,
    /// Serve a CoPA-Map (from `chronomap activity fit`) as NAME=FILE at /v1/activity/NAME/.
    #[arg(long, value_parser = parse_named_file, value_delimiter = ',')]
    pub activity: Vec<(String, PathBuf)>,
    /// A Nav2 map (YAML) of an --activity model as NAME=MAP.yaml: cells on its walls are left out.
    #[arg(long, value_parser = parse_named_file, value_delimiter = ',')]
    pub activity_map: Vec<(String, PathBuf)>,
    /// Watch a running behavior tree through its Groot2 publisher ([NAME=]HOST:PORT, the
    /// publisher's port: BehaviorTree.CPP's Groot2Publisher, Nav2's, `chronomap bt run
    /// --groot2`): its nodes' statuses, transitions and blackboards at /v1/bt/monitors and in
    /// the viewer's "Behavior trees" tab, any number of trees of any size. Repeat the flag or
    /// separate them by commas.
    #[arg(long, value_name = "[NAME=]HOST:PORT", value_delimiter = ',',
          value_parser = chronomap_serve::bt_monitor::MonitorTarget::parse)]
    pub bt_monitor: Vec<chronomap_serve::bt_monitor::MonitorTarget>,
}

fn parse_non_negative(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(x) if x.is_finite() && x >= 0.0 => Ok(x),
        _ => Err(format!("{text:?} is not a number of seconds >= 0")),
    }
}

fn parse_host_name(text: &str) -> Result<String, String> {
    let name = text.trim().trim_end_matches('.').to_ascii_lowercase();
    let ok = !name.is_empty()
        && name.len() <= 253
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'.');
    if ok {
        Ok(name)
    } else {
        Err(format!(
            "{text:?} is not a host name (letters, digits, '-' and '.')"
        ))
    }
}

pub(super) fn parse_named_file(text: &str) -> Result<(String, PathBuf), String> {
    match text.split_once('=') {
        Some((name, file))
            if !name.is_empty()
                && !file.is_empty()
                && name
                    .bytes()
                    .all(|b| b.is_ascii_alphanumeric() || b"-_.".contains(&b)) =>
        {
            Ok((name.to_owned(), PathBuf::from(file)))
        }
        _ => Err(format!(
            "{text:?} is not NAME=FILE (NAME of letters, digits, '-', '_' or '.')"
        )),
    }
}

/// `chronomap client`.
#[derive(Debug, Args)]
pub struct ClientArgs {
    /// Service address.
    #[arg(long, default_value = "http://127.0.0.1:8470", env = "CHRONOMAP_URL")]
    pub url: String,
    /// File holding the bearer token for writes (as printed by `chronomap serve`).
    #[arg(long, env = "CHRONOMAP_TOKEN_FILE")]
    pub token_file: Option<PathBuf>,
    /// Print the answer as one JSON object (`health` and `view` always do).
    #[arg(long, global = true)]
    pub json: bool,
    /// Answer only after applying the log up to this position: the `seq` a write returned, on
    /// any node of a fleet (header `Chronomap-Read-After`; docs/fleet.md).
    #[arg(long, global = true, value_name = "SEQ")]
    pub read_after: Option<u64>,
    /// What to ask.
    #[command(subcommand)]
    pub command: ClientCommand,
}

/// `chronomap client` subcommands.
#[derive(Debug, Subcommand)]
pub enum ClientCommand {
    /// Service health.
    Health,
    /// All models (with --prefix, those whose ids start with it: one robot's).
    List {
        /// Only ids starting with this text, e.g. `robot7/`.
        #[arg(long)]
        prefix: Option<String>,
    },
    /// A model's parameters.
    View {
        /// Model id.
        id: String,
    },
    /// Create a model.
    Create {
        /// Model id.
        id: String,
        /// Model spec: fremen:K, persistence:K, hist:N, recent:N:PERIOD:CYCLES, pergam:K, stm,
        /// mean learn online; auto,
        /// fremen:auto, pergam:auto, fft:L, ... keep their observations and are refitted.
        #[arg(long, default_value = "fremen:2")]
        model: String,
        /// Value range LO,HI of continuous states (`--range 0,10`, `--range -5,5`): one
        /// argument, so that the flag after it stays a flag.
        #[arg(long, value_delimiter = ',', num_args = 1, allow_hyphen_values = true)]
        range: Option<Vec<f64>>,
        /// A calendar of days off (one `YYYY-MM-DD` UTC date per line, optionally a name, as
        /// `eval --days-off` reads it): observations on those days are not learned, and the
        /// days are predicted as the Sunday before.
        #[arg(long)]
        days_off: Option<PathBuf>,
    },
    /// Remove a model.
    Remove {
        /// Model id.
        id: String,
    },
    /// Refit a model fitted on a whole series (auto, fremen:auto, ...) on its kept
    /// observations now; prints what the fit chose.
    Refit {
        /// Model id.
        id: String,
    },
    /// Add observations from a `t value` file (or TIMES,VALUES files), in batches.
    #[command(
        after_help = "Example:\n  chronomap client add lab-door --file data/door_greg_2016/training_data.txt.xz --model fremen:2"
    )]
    Add {
        /// Model id.
        id: String,
        /// Observations: one `t value` file, or TIMES,VALUES (two line-aligned files). A
        /// `t value` file's values may be any finite numbers, for a model of continuous values
        /// (created with --range), which checks them against its range.
        #[arg(long, value_parser = parse_series_source)]
        file: SeriesSource,
        /// Spec of the model to create if it does not exist.
        #[arg(long)]
        model: Option<String>,
        /// Observations per request.
        #[arg(long, default_value_t = 100_000)]
        batch: usize,
    },
    /// Predict p(t): at given times, or from --from to --to every --step seconds.
    #[command(
        after_help = "Example:\n  chronomap client predict lab-door --from 2016-03-21T00:00Z --to 2016-03-22T00:00Z --step 3600"
    )]
    Predict {
        /// Model id.
        id: String,
        /// Times: unix seconds or ISO 8601 (2016-03-21T13:00Z; UTC unless an offset is given);
        /// several after the flag, the flag repeated, or separated by commas.
        #[arg(
            long,
            num_args = 1..,
            value_delimiter = ',',
            value_parser = parse_time,
            conflicts_with_all = ["from", "to"]
        )]
        at: Vec<f64>,
        /// First time of a range (unix seconds or ISO 8601).
        #[arg(long, value_parser = parse_time, requires = "to")]
        from: Option<f64>,
        /// Last time of a range (unix seconds or ISO 8601).
        #[arg(long, value_parser = parse_time, requires = "from")]
        to: Option<f64>,
        /// Step of a range (s).
        #[arg(long, default_value_t = 3600.0, value_parser = parse_positive)]
        step: f64,
        /// Order to predict with.
        #[arg(long)]
        order: Option<usize>,
        /// For a model of continuous values (created with --range): also the central
        /// prediction interval of this coverage, strictly between 0 and 1 (e.g. 0.9), in the
        /// range.
        #[arg(long, value_parser = parse_open_probability)]
        coverage: Option<f64>,
    },
    /// p(t) of many models at one time.
    Forecast {
        /// Model ids: comma-separated or the flag repeated.
        #[arg(long, value_delimiter = ',', required = true)]
        ids: Vec<String>,
        /// The time: unix seconds or ISO 8601 (2016-03-21T13:00Z).
        #[arg(long, value_parser = parse_time)]
        at: f64,
        /// Order for every model.
        #[arg(long)]
        order: Option<usize>,
    },
    /// Errors per order on a `t value` file.
    Evaluate {
        /// Model id.
        id: String,
        /// Observations.
        #[arg(long, value_parser = parse_series_source)]
        file: SeriesSource,
        /// Largest order.
        #[arg(long)]
        max_order: Option<usize>,
    },
}
