//! The messages every layer speaks: plant samples, commands, telemetry, parameter sets, the
//! optimiser's acknowledgements and model estimates. Plain fixed-size `#[repr(C)]` data with no
//! pointers, so the transport can put them in shared memory as they are: with feature
//! `iceoryx2` this crate marks them zero-copy sendable and gives them their versioned iceoryx2
//! type names (through iceoryx2's dependency-free trait crate). Control laws, plants and the
//! simulation use them without the feature, linking nothing of the transport. The bottom of the
//! workspace: without the feature it depends on serde alone, so every other crate (and a
//! process in another language reading the same layouts) can take it.
//!
//! The crate is versioned on its own: its major version is the contract version ([`CONTRACT`]),
//! the `.vN` at the end of every iceoryx2 type name. A layout change bumps both.

/// The contract version: the `.vN` of the type names, the crate's major version.
pub const CONTRACT: u32 = 1;

/// Largest number of joints/inputs/outputs a message carries (8-joint arms fit).
pub const MAX_JOINTS: usize = 8;
/// Largest plant state vector a message carries (positions, velocities and extra states).
pub const MAX_STATES: usize = 32;
/// Largest parameter set; a model with more values travels in parts (`ParamSet::model_sets`).
pub const MAX_PARAMS: usize = 1024;
/// Values before a `ParamKind::ModelPart` set's share of the model: kind, offset, total.
pub const PART_HEADER: usize = 3;
/// A `ParamKind::ModelPart` set's share of the model: the values after its header.
pub const PART_VALUES: usize = MAX_PARAMS - PART_HEADER;

/// A `u32` code on the wire that is not one of the enum's: a message from another version of
/// the contract, or a corrupt one. Reading it is an error, never a silent default.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct UnknownCode {
    /// The enum the code was read as.
    pub what: &'static str,
    /// The code read from the wire.
    pub code: u32,
}

impl std::fmt::Display for UnknownCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "unknown {} code {}", self.what, self.code)
    }
}

impl std::error::Error for UnknownCode {}

/// A `#[repr(u32)]` enum carried as its code in a message: `code()` writes it, `TryFrom<u32>`
/// reads it back and refuses any other value, `ALL` lists the variants (for tests and
/// documentation of the contract). In JSON files (controller.json, summary.json) it is its
/// snake_case name.
macro_rules! wire_enum {
    ($(#[$m:meta])* pub enum $name:ident { $($(#[$vm:meta])* $v:ident = $c:literal,)* }) => {
        $(#[$m])*
        #[repr(u32)]
        #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
        #[serde(rename_all = "snake_case")]
        pub enum $name { $($(#[$vm])* $v = $c,)* }

        impl $name {
            /// Every variant, in code order.
            pub const ALL: &'static [$name] = &[$($name::$v),*];
            /// The code the message carries.
            pub const fn code(self) -> u32 {
                self as u32
            }
        }

        impl TryFrom<u32> for $name {
            type Error = UnknownCode;
            fn try_from(code: u32) -> Result<Self, UnknownCode> {
                match code {
                    $($c => Ok($name::$v),)*
                    _ => Err(UnknownCode { what: stringify!($name), code }),
                }
            }
        }
    };
}

/// `PlantState::flags`: the plant applied its safe command because commands stopped arriving.
pub const STATE_FLAG_SAFE: u32 = 1;
/// `PlantState::flags`: the scenario is over; this is the last message of the run.
pub const STATE_FLAG_END: u32 = 2;

/// One sample of the plant, published by the plant process every control period.
///
/// Fixed-size and `repr(C)`, so it travels by shared memory as it is: the counts say how many
/// entries of each array are valid; the rest are ignored (zero by default).
///
/// ```
/// use evoloop_msg::{PlantState, STATE_FLAG_END};
///
/// // A two-joint arm's sample 41 at t = 0.041 s, measured by encoders.
/// let mut s = PlantState { seq: 41, t: 0.041, n_q: 2, n_y: 2, ..PlantState::default() };
/// s.y[..2].copy_from_slice(&[0.1005, -0.2495]);
/// assert_eq!(&s.y[..s.n_y as usize], &[0.1005, -0.2495]);
/// // The last sample of a run says so in its flags.
/// s.flags |= STATE_FLAG_END;
/// assert!(s.flags & STATE_FLAG_END != 0);
/// ```
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantState {
    /// Sample index, 0, 1, 2, ...
    pub seq: u64,
    /// CLOCK_MONOTONIC time at which the sample was taken, ns.
    pub stamp_ns: u64,
    /// Simulated time of the sample, s.
    pub t: f64,
    /// Number of valid entries in `x_true`: the plant's states.
    pub n_x: u32,
    /// Number of valid entries in `q_true` and `qd_true`: the plant's joints.
    pub n_q: u32,
    /// Number of valid entries in `y`: the plant's measured outputs.
    pub n_y: u32,
    /// `STATE_FLAG_*` bits.
    pub flags: u32,
    /// The simulator's true full state vector in the plant's documented order: what no sensor
    /// gives. A control law that reads it (full-state feedback) says so in its docs.
    pub x_true: [f64; MAX_STATES],
    /// True joint (body) positions (exact, noise-free).
    pub q_true: [f64; MAX_JOINTS],
    /// True joint (body) velocities, the time derivatives of `q_true` (exact, noise-free).
    pub qd_true: [f64; MAX_JOINTS],
    /// Measured outputs: what the plant's sensors report, with their noise and quantisation.
    pub y: [f64; MAX_JOINTS],
    /// The command that was applied over the interval that ended at this sample.
    pub u_applied: [f64; MAX_JOINTS],
}

impl Default for PlantState {
    fn default() -> Self {
        Self {
            seq: 0,
            stamp_ns: 0,
            t: 0.0,
            n_x: 0,
            n_q: 0,
            n_y: 0,
            flags: 0,
            x_true: [0.0; MAX_STATES],
            q_true: [0.0; MAX_JOINTS],
            qd_true: [0.0; MAX_JOINTS],
            y: [0.0; MAX_JOINTS],
            u_applied: [0.0; MAX_JOINTS],
        }
    }
}

/// The controller's answer to one state sample.
///
/// ```
/// use evoloop_msg::Command;
///
/// // Cycle 7 answers state 41 with two torques, under parameter set 3.
/// let mut c = Command { cycle: 7, state_seq: 41, param_version: 3, n_u: 2, ..Command::default() };
/// c.u[..2].copy_from_slice(&[1.5, -0.25]);
/// assert_eq!(&c.u[..c.n_u as usize], &[1.5, -0.25]);
/// ```
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Command {
    /// Controller cycle index.
    pub cycle: u64,
    /// `PlantState::seq` this command answers.
    pub state_seq: u64,
    /// CLOCK_MONOTONIC time at which the command was published, ns.
    pub stamp_ns: u64,
    /// Parameter-set version in service when the command was computed.
    pub param_version: u64,
    /// Number of valid entries in `u`: the controller's outputs, one per plant input.
    pub n_u: u32,
    /// Padding, 0.
    pub _pad: u32,
    /// The command, one value per plant input in that input's unit; the first `n_u` are valid.
    pub u: [f64; MAX_JOINTS],
}

wire_enum! {
/// Why a parameter set was refused (`Telemetry::param_code`).
pub enum ParamCode {
    /// Nothing happened to the parameters this cycle.
    None = 0,
    /// The set passed the controller's checks and is in service from this cycle.
    Accepted = 1,
    /// A value is NaN or infinite (`Telemetry::param_index` names it).
    RejectedNonFinite = 2,
    /// The set is for another controller kind (`ParamSet::kind`).
    RejectedWrongKind = 3,
    /// The set's number of values is not the one the controller takes.
    RejectedWrongLength = 4,
    /// A value is outside the configured bounds (`Telemetry::param_index` names it).
    RejectedOutOfBounds = 5,
    /// The version is not newer than the one in service.
    RejectedStale = 6,
    /// The closed loop would be unstable on the controller's plant model.
    RejectedUnstable = 7,
    /// A model set whose M-hat is not positive definite (or far less so than the model it
    /// would replace) on the model's probe positions.
    RejectedNotPositiveDefinite = 8,
    /// A trial set's repetition ended: its fallback is back in service.
    TrialEnded = 9,
    /// A trial set left the safety envelope: its fallback was restored in the same cycle.
    TrialAborted = 10,
    /// A trial set named a fallback the controller does not hold.
    RejectedUnknownFallback = 11,
    /// Stable on the configured model but not on the latest estimate of the plant.
    RejectedUnstableOnEstimate = 12,
    /// A part of a model sent in parts (`ParamKind::ModelPart`) came without the parts before
    /// it, or its header disagrees with them: the model is dropped whole, none of it in service.
    RejectedPartMissing = 13,
}
}

impl ParamCode {
    /// Whether the set was refused (a trial's end or abort is not a refusal).
    ///
    /// ```
    /// use evoloop_msg::ParamCode;
    ///
    /// assert!(!ParamCode::Accepted.is_rejection());
    /// assert!(ParamCode::RejectedPartMissing.is_rejection());
    /// // Telemetry carries the code as a number; an unknown one is an error, not a default.
    /// assert_eq!(ParamCode::try_from(1), Ok(ParamCode::Accepted));
    /// assert!(ParamCode::try_from(9999).is_err());
    /// ```
    pub fn is_rejection(self) -> bool {
        !matches!(
            self,
            Self::None | Self::Accepted | Self::TrialEnded | Self::TrialAborted
        )
    }

    /// Short reason for logs and reports.
    pub fn reason(self) -> &'static str {
        match self {
            Self::None => "none",
            Self::Accepted => "accepted",
            Self::RejectedNonFinite => "rejected: a value is NaN or infinite",
            Self::RejectedWrongKind => "rejected: parameter set is for another controller kind",
            Self::RejectedWrongLength => "rejected: wrong number of values",
            Self::RejectedOutOfBounds => "rejected: a value is outside the configured bounds",
            Self::RejectedStale => "rejected: version is not newer than the one in service",
            Self::RejectedUnstable => {
                "rejected: the closed loop would be unstable on the controller's plant model"
            }
            Self::RejectedNotPositiveDefinite => {
                "rejected: the model's M-hat is not safely positive definite on its probes"
            }
            Self::TrialEnded => "trial ended: its fallback is back in service",
            Self::TrialAborted => "trial aborted: it left the safety envelope; fallback restored",
            Self::RejectedUnknownFallback => {
                "rejected: a trial naming a fallback the controller does not hold"
            }
            Self::RejectedUnstableOnEstimate => {
                "rejected: the closed loop would be unstable on the latest estimate of the plant"
            }
            Self::RejectedPartMissing => {
                "rejected: a model sent in parts lost a part or mixed two models; none of it used"
            }
        }
    }
}

/// `Telemetry::flags`: the state the controller used was older than the stale limit.
pub const TELEMETRY_FLAG_STALE: u32 = 1;
/// `Telemetry::flags`: this cycle's lateness plus compute time overran its period.
pub const TELEMETRY_FLAG_OVERRUN: u32 = 2;
/// `Telemetry::flags`: this cycle started a full period or more after its deadline.
pub const TELEMETRY_FLAG_MISSED: u32 = 4;
/// `Telemetry::flags`: the plant's state was refused (a count not the configured plant's, or a
/// value the law reads not finite); the law did not run and the safe command went out.
pub const TELEMETRY_FLAG_REFUSED_STATE: u32 = 8;

/// One controller cycle as the controller saw it.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Telemetry {
    /// Controller cycle index (as `Command::cycle`).
    pub cycle: u64,
    /// `PlantState::seq` of the state this cycle used.
    pub state_seq: u64,
    /// Simulated time of the state used, s.
    pub t: f64,
    /// Wake-up lateness against the cycle's absolute deadline (0 in lockstep), ns.
    pub lateness_ns: i64,
    /// Time spent computing the control law and publishing, ns.
    pub compute_ns: u64,
    /// Age of the state sample when the control law used it, ns.
    pub state_age_ns: u64,
    /// The reference (set-point) of the first output at this cycle, in that output's unit.
    pub reference: f64,
    /// `reference` minus the first measured output `PlantState::y[0]`, in that output's unit.
    pub tracking_error: f64,
    /// Number of valid entries in `u`: the controller's outputs, one per plant input.
    pub n_u: u32,
    /// `TELEMETRY_FLAG_*` bits.
    pub flags: u32,
    /// The command sent for this cycle's state (the safe command for a refused state), one value
    /// per plant input; the first `n_u` are valid.
    pub u: [f64; MAX_JOINTS],
    /// Parameter version in service after this cycle.
    pub param_version: u64,
    /// Version concerned by `param_code` (accepted or rejected this cycle).
    pub param_event_version: u64,
    /// `ParamCode` as u32.
    pub param_code: u32,
    /// Index of the offending value for `RejectedOutOfBounds`/`RejectedNonFinite`.
    pub param_index: u32,
    /// Cycles since the start of the run whose lateness plus compute time exceeded the period
    /// (a running count; always 0 in lockstep, where no cycle is late).
    pub overruns: u64,
    /// Control periods that passed without a cycle (missed deadlines, those before the first state
    /// included) since the start of the run; always 0 in lockstep.
    pub missed: u64,
    /// Number of valid entries in `law`.
    pub n_law: u32,
    /// Padding, 0.
    pub _pad: u32,
    /// The law's own values of this cycle (`Controller::log_values`, its run.csv columns; a
    /// fuzzy selector's active model and memberships), the first `n_law` valid.
    pub law: [f64; MAX_LAW_VALUES],
}

/// Most law values telemetry carries: a fuzzy selector's active model and up to 8 memberships.
pub const MAX_LAW_VALUES: usize = 9;

wire_enum! {
/// What a parameter set is for (`ParamSet::kind`, as its code): the gains of one controller
/// kind, or a model for a controller that takes models besides its gains.
pub enum ParamKind {
    /// Gains of `state_feedback`: K = [k_1..k_n, k_{n+1}] with n = n_x, k_{n+1} on the integral.
    StateFeedback = 1,
    /// Gains of `pd_servo`: [Kp_1..Kp_n, Kd_1..Kd_n], per joint.
    PdServo = 2,
    /// Gains of `computed_torque`: [Kp_1..Kp_n, Kv_1..Kv_n], per joint.
    ComputedTorque = 3,
    /// Gains of `pid` with `anti_windup = "fuzzy"`: [Kp, Tv, v0e, v1e, v0K/v1K, C_i, C_e].
    PidFuzzyAntiWindup = 4,
    /// Gains of `pid` with `anti_windup = "none"`: [Kp, Tv, Ki].
    Pid = 5,
    /// Gains of `pid` with `anti_windup = "clamping"` (conditional integration): [Kp, Tv, Ki].
    PidClamping = 6,
    /// Gains of `pid` with `anti_windup = "back_calculation"`: [Kp, Tv, Ki, Kb].
    PidBackCalculation = 7,
    /// Gains of `pid` with `anti_windup = "integrator_clamp"`: [Kp, Tv, Ki].
    PidIntegratorClamp = 8,
    /// Gains of `fuzzy_computed_torque`: [Kp_1..Kp_n, Kv_1..Kv_n], per joint.
    FuzzyComputedTorque = 9,
    /// An identified RKGNN model for one slot of a fuzzy computed-torque controller: values =
    /// [slot, the network's parameters in `evoloop_rkgnn::Layout` order].
    RkgnnModel = 10,
    /// A rigid-body model for a computed-torque controller: values = the parameters in the
    /// regressor's order, ten per body, then viscous and Coulomb friction per joint, then the
    /// armature per joint (`identify::Columns::PLANT`).
    RigidBodyModel = 11,
    /// The genes of a fuzzy network controller (`fuzzy::codec::Codec` order: per variable the
    /// centre genes then the widths, then the scaling factors).
    FuzzyNetwork = 12,
    /// One part of a model set larger than one parameter set (`ParamSet::model_sets`): values =
    /// [the whole's kind code, offset, total length, the whole's values[offset..]]. Every part
    /// carries the model's version and `apply_at_seq`; the controller gathers them in order and
    /// checks and applies the whole at its last part, as one set of the whole's kind.
    ModelPart = 13,
}
}

/// A parameter set from the optimiser to the controller.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamSet {
    /// Strictly increasing; the controller refuses a version not newer than the one in service.
    pub version: u64,
    /// State sequence number at whose cycle the set is to be applied; 0 = the next cycle.
    /// Lockstep runs use it so a swap lands on the same sample every run.
    pub apply_at_seq: u64,
    /// The optimiser's expected cost of this set on its model (NaN when unknown).
    pub expected_cost: f64,
    /// 0: a set that stays in service. Otherwise a trial (the direct scheme): it serves the cycles
    /// of states `apply_at_seq..until_seq` under the safety envelope, then the controller returns
    /// to its fallback; it returns at once when the envelope is left (`ParamCode::TrialAborted`).
    pub until_seq: u64,
    /// A trial's fallback: the version of the set restored after it, which must be the
    /// controller's current fallback or its last trial (that trial becoming the fallback).
    pub fallback_version: u64,
    /// A `ParamKind`'s code (`ParamSet::param_kind` reads it back, refusing an unknown one).
    pub kind: u32,
    /// Number of valid entries in `values`.
    pub n: u32,
    /// The parameters, in the order the `kind` defines; the first `n` are valid.
    pub values: [f64; MAX_PARAMS],
}

impl Default for ParamSet {
    fn default() -> Self {
        Self {
            version: 0,
            apply_at_seq: 0,
            expected_cost: f64::NAN,
            until_seq: 0,
            fallback_version: 0,
            kind: 0,
            n: 0,
            values: [0.0; MAX_PARAMS],
        }
    }
}

impl ParamSet {
    /// A set of `kind` carrying `values` (at most `MAX_PARAMS` of them), applied at sample
    /// `apply_at_seq` (0: at once). Allocation-free.
    ///
    /// ```
    /// use evoloop_msg::{ParamKind, ParamSet, UnknownCode};
    ///
    /// // A P-D servo's gains (k_p, k_d per joint), version 3, to be applied at once.
    /// let set = ParamSet::new(3, 0, ParamKind::PdServo, &[100.0, 20.0]);
    /// assert_eq!(set.values(), &[100.0, 20.0]);
    /// assert_eq!(set.param_kind(), Ok(ParamKind::PdServo));
    /// // A kind code from another contract version is refused, not read as a default.
    /// let foreign = ParamSet { kind: 99, ..set };
    /// assert_eq!(foreign.param_kind(), Err(UnknownCode { what: "ParamKind", code: 99 }));
    /// ```
    pub fn new(version: u64, apply_at_seq: u64, kind: ParamKind, values: &[f64]) -> Self {
        let n = values.len().min(MAX_PARAMS);
        let mut set = ParamSet {
            version,
            apply_at_seq,
            kind: kind.code(),
            n: n as u32,
            ..ParamSet::default()
        };
        set.values[..n].copy_from_slice(&values[..n]);
        set
    }

    /// The set's valid values, `values[..n]` (at most `MAX_PARAMS`, whatever `n` says).
    pub fn values(&self) -> &[f64] {
        &self.values[..(self.n as usize).min(MAX_PARAMS)]
    }

    /// How many sets `model_sets` sends a model of `len` values in.
    pub fn model_set_count(len: usize) -> usize {
        if len <= MAX_PARAMS {
            1
        } else {
            len.div_ceil(PART_VALUES)
        }
    }

    /// A model set of `kind` with `values` of any length, as the sets that carry it: the set
    /// itself where it fits, otherwise `ModelPart` sets in order, each with at most
    /// `PART_VALUES` of the model's values after its header. All share `version` and
    /// `apply_at_seq`, and carry `expected_cost`.
    pub fn model_sets(
        version: u64,
        apply_at_seq: u64,
        expected_cost: f64,
        kind: ParamKind,
        values: &[f64],
    ) -> Vec<ParamSet> {
        let with_cost = |mut set: ParamSet| {
            set.expected_cost = expected_cost;
            set
        };
        if values.len() <= MAX_PARAMS {
            return vec![with_cost(ParamSet::new(
                version,
                apply_at_seq,
                kind,
                values,
            ))];
        }
        let total = values.len() as f64;
        values
            .chunks(PART_VALUES)
            .enumerate()
            .map(|(i, part)| {
                let mut set = ParamSet::new(version, apply_at_seq, ParamKind::ModelPart, &[]);
                set.values[..PART_HEADER].copy_from_slice(&[
                    kind.code() as f64,
                    (i * PART_VALUES) as f64,
                    total,
                ]);
                set.values[PART_HEADER..PART_HEADER + part.len()].copy_from_slice(part);
                set.n = (PART_HEADER + part.len()) as u32;
                with_cost(set)
            })
            .collect()
    }

    /// What the set is for; an unknown code (a sender of another version, a corrupt set) is an
    /// error, never a kind.
    pub fn param_kind(&self) -> Result<ParamKind, UnknownCode> {
        ParamKind::try_from(self.kind)
    }
}

/// Lockstep pacing: the optimiser has consumed every sample up to `through_seq` and published
/// whatever it meant to publish before it; the plant may go past that sample.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OptimiserAck {
    /// The optimiser has consumed every sample up to this `PlantState::seq`; `u64::MAX`: a
    /// rejoining optimiser releases the plant.
    pub through_seq: u64,
}

/// The optimiser's progress (indirect and identify schemes), published after each tuning
/// epoch, for watchers (`evoloop top`); nothing on the control path reads it.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, serde::Serialize)]
pub struct OptimiserStatus {
    /// Plant time of the last epoch.
    pub t: f64,
    /// Tuning epochs ended so far.
    pub epochs: u64,
    /// Sets published so far.
    pub published: u64,
    /// The last epoch's best cost on the model (infinite: it loses the plant).
    pub best_cost: f64,
    /// The cost of the set in service on the same model as `best_cost` (infinite: it loses the
    /// plant).
    pub in_service_cost: f64,
}

/// The optimiser's model estimate (indirect scheme), published at 10 Hz of plant time: the
/// parameter that changes in operation (maglev: ball mass, kg; two-mass: spring constant) with
/// its standard deviation, and the version of the last set the optimiser published.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ModelEstimate {
    /// Plant time of the estimate, s.
    pub t: f64,
    /// The estimated parameter, in its own unit (maglev: ball mass, kg; two-mass: spring
    /// constant; a linear plant's model: its input gain, the leading numerator coefficient).
    pub value: f64,
    /// Standard deviation of `value`, in the same unit; infinite while no fit has been adopted.
    pub std: f64,
    /// Version of the last parameter set the optimiser published (0: none yet).
    pub last_version: u64,
    /// The controller adopts the estimate (as the model it checks new sets on) at the cycle of
    /// this sample, or at once when 0. Lockstep: the sample after the next synchronisation point,
    /// which the plant cannot pass before the estimate has been delivered, so every run of a
    /// seed checks each set on the same estimate.
    pub apply_at_seq: u64,
}

/// The most poles of a `LinearEstimate`'s transfer function.
pub const MAX_ESTIMATE_POLES: usize = 4;

/// The general indirect scheme's estimated transfer function (an `lti` plant or a plant of the
/// user's own), published beside `ModelEstimate` at 10 Hz of plant time, for the controller to
/// check new sets on: b(s) / a(s), descending powers, `poles + 1` values of each in use, `den`
/// monic and `num[0] = 0` (strictly proper).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct LinearEstimate {
    /// Plant time of the estimate, s.
    pub t: f64,
    /// Adopted at the cycle of this sample, or at once when 0 (as `ModelEstimate`'s).
    pub apply_at_seq: u64,
    /// Number of poles: the degree of a(s); `poles + 1` entries of `num` and `den` are in use.
    pub poles: u32,
    /// Padding, 0.
    pub reserved: u32,
    /// Numerator b(s), descending powers; `num[0] = 0`.
    pub num: [f64; MAX_ESTIMATE_POLES + 1],
    /// Denominator a(s), descending powers; monic, `den[0] = 1`.
    pub den: [f64; MAX_ESTIMATE_POLES + 1],
}

wire_enum! {
    /// What an operator asks of the tuner of a running run (`evoloop operator`, `evoloop top`).
    pub enum OperatorAction {
        /// Propose nothing new: the trial (or epoch) under way ends, the set in service stays.
        Hold = 1,
        /// Tune again after a hold.
        Resume = 2,
        /// Put an earlier set back in service (`OperatorCommand::version`; 0 = the set in
        /// service before tuning) and hold.
        Revert = 3,
        /// End tuning for this run: the set in service stays (the direct scheme: the best found).
        Stop = 4,
    }
}

impl OperatorAction {
    /// The action's lower-case name, as `evoloop operator` prints it (and JSON files spell it).
    pub fn name(self) -> &'static str {
        match self {
            Self::Hold => "hold",
            Self::Resume => "resume",
            Self::Revert => "revert",
            Self::Stop => "stop",
        }
    }
}

wire_enum! {
    /// How the tuner answered an operator's command.
    pub enum OperatorOutcome {
        /// Done: the state it leaves (held, reverted at `version`, stopped) holds from `t`.
        Done = 0,
        /// Revert: no set of that version is kept (`node::optimiser::SETS_KEPT`).
        UnknownVersion = 1,
        /// Tuning has stopped; only a revert is still taken.
        Stopped = 2,
        /// Nothing to operate: no tuning scheme runs (a schedule, or off), or a revert where
        /// the scheme publishes models, not gain sets (identification).
        NotHere = 3,
        /// The command's action code is not one this build knows.
        UnknownAction = 4,
    }
}

impl OperatorOutcome {
    /// Short reason for the operator's output (`evoloop operator`, `evoloop top`).
    pub fn reason(self) -> &'static str {
        match self {
            Self::Done => "done",
            Self::UnknownVersion => "no set of that version is kept from this run",
            Self::Stopped => "tuning has stopped (a revert is still taken)",
            Self::NotHere => {
                "nothing to operate here: no tuning scheme runs, or it publishes models (no revert)"
            }
            Self::UnknownAction => "unknown action code",
        }
    }
}

/// An operator's command to the optimiser (topic `operator`). `id` is the sender's own number,
/// echoed in the answer.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OperatorCommand {
    /// The sender's own number for this command, echoed in `OperatorAck::id`.
    pub id: u64,
    /// `OperatorAction::code`.
    pub action: u32,
    /// Padding, 0.
    pub _pad: u32,
    /// Revert: the version to put back (0: the set before tuning).
    pub version: u64,
}

/// The optimiser's answer (topic `operator_ack`), also recorded in optimiser.json `operator`.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct OperatorAck {
    /// `OperatorCommand::id` of the command this answers.
    pub id: u64,
    /// `OperatorCommand::action` of the command this answers, echoed.
    pub action: u32,
    /// `OperatorOutcome::code`.
    pub outcome: u32,
    /// Plant time at which the optimiser took it.
    pub t: f64,
    /// Revert: the version of the set it published (the earlier values under a new version);
    /// otherwise the last version it published.
    pub version: u64,
}

#[cfg(feature = "iceoryx2")]
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

/// The message types go into iceoryx2's shared memory as they are (its `ZeroCopySend`, from the
/// dependency-free trait crate, so this crate links no transport). Their iceoryx2 names carry a version
/// suffix because iceoryx2 checks only name, size and alignment when a service opens: change a
/// layout, bump the version.
#[cfg(feature = "iceoryx2")]
macro_rules! zero_copy {
    ($($t:ident => $name:literal),* $(,)?) => {$(
        // SAFETY: `#[repr(C)]`, `Copy`, fields only f64/u64/u32 and fixed arrays of them: no
        // pointers or references, the same layout in every process of one build.
        unsafe impl ZeroCopySend for $t {
            unsafe fn type_name() -> &'static str {
                $name
            }
        }
    )*};
}
#[cfg(feature = "iceoryx2")]
zero_copy!(
    PlantState => "evoloop::PlantState.v1",
    Command => "evoloop::Command.v1",
    Telemetry => "evoloop::Telemetry.v1",
    ParamSet => "evoloop::ParamSet.v1",
    OptimiserAck => "evoloop::OptimiserAck.v1",
    ModelEstimate => "evoloop::ModelEstimate.v1",
    OptimiserStatus => "evoloop::OptimiserStatus.v1",
    OperatorCommand => "evoloop::OperatorCommand.v1",
    OperatorAck => "evoloop::OperatorAck.v1",
    LinearEstimate => "evoloop::LinearEstimate.v1",
);

#[cfg(test)]
mod tests {
    use super::*;
    use std::mem::{align_of, offset_of, size_of};

    /// The contract version is the crate's major version, so a layout change cannot ship as
    /// a minor release of the message crate.
    #[test]
    fn the_contract_version_is_the_major_version() {
        let major: u32 = env!("CARGO_PKG_VERSION_MAJOR").parse().unwrap();
        assert_eq!(CONTRACT, major);
    }

    /// Every iceoryx2 type name ends in the contract version.
    #[cfg(feature = "iceoryx2")]
    #[test]
    fn every_type_name_carries_the_contract_version() {
        use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
        // SAFETY: type_name only returns the static name.
        let names = unsafe {
            [
                PlantState::type_name(),
                Command::type_name(),
                Telemetry::type_name(),
                ParamSet::type_name(),
                OptimiserAck::type_name(),
                ModelEstimate::type_name(),
                OptimiserStatus::type_name(),
                OperatorCommand::type_name(),
                OperatorAck::type_name(),
                LinearEstimate::type_name(),
            ]
        };
        for n in names {
            assert!(n.ends_with(&format!(".v{CONTRACT}")), "{n}");
        }
    }

    #[test]
    fn every_code_reads_back_as_itself_and_no_other_value_reads_at_all() {
        for k in ParamKind::ALL {
            assert_eq!(ParamKind::try_from(k.code()), Ok(*k));
        }
        for c in ParamCode::ALL {
            assert_eq!(ParamCode::try_from(c.code()), Ok(*c));
        }
        // Codes are 1..=13 and 0..=13, dense: anything else is unknown, named as what.
        for bad in [0, 14, 99, u32::MAX] {
            let e = ParamKind::try_from(bad).unwrap_err();
            assert_eq!((e.what, e.code), ("ParamKind", bad));
            assert_eq!(e.to_string(), format!("unknown ParamKind code {bad}"));
        }
        assert!(ParamCode::try_from(14).is_err());
        assert_eq!(ParamKind::ALL.len(), 13);
        assert_eq!(ParamCode::ALL.len(), 14);
        let set = ParamSet::new(1, 0, ParamKind::RkgnnModel, &[1.0]);
        assert_eq!(set.param_kind(), Ok(ParamKind::RkgnnModel));
        let corrupt = ParamSet { kind: 77, ..set };
        assert!(corrupt.param_kind().is_err());
    }

    /// The layouts other processes read (the type names end in `.v1`): sizes and the offsets of
    /// the fields a reader needs first. A change here is a new contract version: bump the
    /// `zero_copy!` name with it, or an old peer opens the service and misreads every sample.
    #[test]
    fn the_message_layouts_are_the_contract_v1() {
        assert_eq!((MAX_JOINTS, MAX_STATES, MAX_PARAMS), (8, 32, 1024));
        // 3 x 8 (seq, stamp, t) + 4 x 4 (counts, flags) + 32 + 4 x 8 f64 arrays.
        assert_eq!(size_of::<PlantState>(), 24 + 16 + 8 * (32 + 4 * 8));
        assert_eq!(offset_of!(PlantState, n_x), 24);
        assert_eq!(offset_of!(PlantState, x_true), 40);
        assert_eq!(offset_of!(PlantState, y), 40 + 8 * (32 + 16));
        assert_eq!(offset_of!(Command, u), 40);
        assert_eq!(offset_of!(ParamSet, kind), 40);
        assert_eq!(offset_of!(ParamSet, values), 48);
        assert_eq!(size_of::<ParamSet>(), 48 + 8 * MAX_PARAMS);
        assert_eq!(size_of::<OptimiserAck>(), 8);
        assert_eq!(size_of::<OptimiserStatus>(), 40);
        assert_eq!(size_of::<ModelEstimate>(), 40);
        assert_eq!(size_of::<OperatorCommand>(), 24);
        assert_eq!(size_of::<OperatorAck>(), 32);
        assert_eq!(size_of::<LinearEstimate>(), 24 + 8 * 10);
        assert_eq!(offset_of!(LinearEstimate, num), 24);
        for a in OperatorAction::ALL {
            assert_eq!(OperatorAction::try_from(a.code()), Ok(*a));
        }
        assert!(OperatorAction::try_from(0).is_err() && OperatorOutcome::try_from(5).is_err());
        for align in [
            align_of::<PlantState>(),
            align_of::<Command>(),
            align_of::<Telemetry>(),
            align_of::<ParamSet>(),
        ] {
            assert_eq!(align, 8);
        }
    }
}
