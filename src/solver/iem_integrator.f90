!> The interface of the explicit time integrators of a dynamic run (RK4, velocity Verlet):
!> what the run driver calls once a step, and what the guards and the memory need to know of
!> them. The driver holds a class(integrator_t) made by iem_integrator_factory and never
!> branches on which one it is (docs/architecture.md, "Run driver and integrators").
!>
!> Contract of a step: the rates at y(t) are evaluated by prepare (into st%acc, or already
!> used by the first part of the step it prepares for dt; with the powers st%p_ext1,
!> st%p_damp1 when prepare evaluated them); step advances y to t + dt and adds the
!> step's local external work and damping dissipation to w_ext, w_damp. An integrator that
!> is not accepted (every integrator rejects a step whose new state is not finite) says so in
!> settle, the same on every rank; the ranks' agreement may complete later, in
!> settle (the driver settles before it reads a state: after prepare, before a checkpoint or a
!> repartition); one that updates y in place (velocity Verlet) keeps the values that a
!> non-finite update would overwrite, and rejected turns what is left into the last good
!> state. Accepted states commit the springs' history. One polymorphic call a step: nothing is
!> dispatched per node or cell. Before a step the driver says in next_plain whether nothing
!> reads the state between that step and the next (no sample, frame, checkpoint or
!> repartitioning; the next step follows): the step may then leave the state part way into
!> the next one (velocity Verlet: the next step's first kick and drift), which rewind brings
!> back should settle reject the step. With local set (runs on more than one rank), a step's
!> verdict stays on its rank: step and settle say whether this rank's new values were finite,
!> no rank waits for another, and after a rejection carry_on lets the rank go on stepping on
!> finite values until the driver's next agreement (docs/architecture.md, "How the ranks agree
!> on a non-finite step").
module iem_integrator
  use mpi_f08, only: MPI_Comm
  use iem_kinds, only: wp
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_state, only: state_t
  implicit none
  private
  public :: integrator_t

  !> An explicit time integrator of the lattice: its name, stability limit, memory needs and
  !> the two calls a step.
  type, abstract :: integrator_t
    !> The communicator over which a step's acceptance is agreed.
    type(MPI_Comm) :: comm
    !> Set by the driver before each step: nothing reads the state of that step's end before
    !> the next step (which follows).
    logical :: next_plain = .false.
    !> With next_plain: the time of that step's end as the driver numbers it (the next step's
    !> t).
    real(wp) :: t_next = 0.0_wp
    !> With next_plain: no history sample reads the evaluation of the step after the next
    !> one (its rates may be evaluated with the next step's).
    logical :: next_forces = .false.
    !> Each step's verdict is this rank's own (no reduction a step): the driver agrees on the
    !> first rejected step at the steps that read the state, and steps again to it.
    logical :: local = .false.
  contains
    procedure :: init => integrator_init
    procedure(integrator_name_i), deferred :: name
    procedure(integrator_stable_dt_i), deferred :: stable_dt
    procedure(integrator_undamped_dt_i), deferred :: undamped_dt
    procedure(integrator_flag_i), deferred :: work_arrays
    procedure(integrator_rejected_i), deferred :: rejected
    procedure(integrator_prepare_i), deferred :: prepare
    procedure(integrator_step_i), deferred :: step
    procedure(integrator_resume_i), deferred :: resume
    procedure :: settle => integrator_settle
    procedure :: rewind => integrator_rewind
    procedure :: carry_on => integrator_carry_on
    procedure :: kick_half => integrator_kick_half
  end type integrator_t

  abstract interface
    !> The integrator's name for messages ('RK4', 'velocity Verlet').
    function integrator_name_i(this) result(name)
      import :: integrator_t
      class(integrator_t), intent(in) :: this
      character(len=:), allocatable :: name
    end function integrator_name_i

    !> Largest stable dt for the highest lattice frequency omega_max (rad/s) with Rayleigh
    !> damping (alpha, beta) and the damping cap omega_cap (0: none).
    pure real(wp) function integrator_stable_dt_i(this, omega_max, alpha, beta, omega_cap)
      import :: integrator_t, wp
      class(integrator_t), intent(in) :: this
      real(wp), intent(in) :: omega_max, alpha, beta, omega_cap
    end function integrator_stable_dt_i

    !> Largest stable dt without damping for the highest frequency omega_max (rad/s).
    pure real(wp) function integrator_undamped_dt_i(this, omega_max)
      import :: integrator_t, wp
      class(integrator_t), intent(in) :: this
      real(wp), intent(in) :: omega_max
    end function integrator_undamped_dt_i

    !> A yes/no property of the integrator (see the bindings).
    pure logical function integrator_flag_i(this)
      import :: integrator_t
      class(integrator_t), intent(in) :: this
    end function integrator_flag_i

    !> Evaluate the rates at y(t) at the top of a step of dt (an accepted state: the springs'
    !> history commits to it); first: the first step of the run (nothing has been evaluated).
    subroutine integrator_prepare_i(this, model, lat, halo, st, t, dt, first)
      import :: integrator_t, model_t, local_lattice_t, halo_t, state_t, wp
      class(integrator_t), intent(inout) :: this
      type(model_t), intent(inout) :: model
      type(local_lattice_t), intent(in) :: lat
      type(halo_t), intent(inout) :: halo
      type(state_t), intent(inout) :: st
      real(wp), intent(in) :: t, dt
      logical, intent(in) :: first
    end subroutine integrator_prepare_i

    !> Advance y from t to t + dt, adding the step's local work and dissipation to w_ext and
    !> w_damp; accepted (the same on every rank) is false when the new state was rejected.
    subroutine integrator_step_i(this, model, lat, halo, st, t, dt, w_ext, w_damp, accepted)
      import :: integrator_t, model_t, local_lattice_t, halo_t, state_t, wp
      class(integrator_t), intent(inout) :: this
      type(model_t), intent(inout) :: model
      type(local_lattice_t), intent(in) :: lat
      type(halo_t), intent(inout) :: halo
      type(state_t), intent(inout) :: st
      real(wp), intent(in) :: t, dt
      real(wp), intent(inout) :: w_ext, w_damp
      logical, intent(out) :: accepted
    end subroutine integrator_step_i

    !> After settle found the last step not accepted: leave in st%y (owned columns 1..n) the
    !> last good state for the guard to write, back = 1 when it is the state of the step before
    !> the rejected one (RK4), 0 when it is the rejected step's own displacements (velocity
    !> Verlet: its velocities are those of the half step before, as note says); first_bad is
    !> this rank's first owned node with a non-finite value of the rejected step (0: none).
    subroutine integrator_rejected_i(this, st, n, back, first_bad, note)
      import :: integrator_t, state_t
      class(integrator_t), intent(inout) :: this
      type(state_t), intent(inout) :: st
      integer, intent(in) :: n
      integer, intent(out) :: back, first_bad
      character(len=:), allocatable, intent(out) :: note
    end subroutine integrator_rejected_i

    !> After a checkpoint was loaded at time t: whatever the integrator must redo so that the
    !> model's energies are those of the loaded state before the first step's sample.
    subroutine integrator_resume_i(this, model, lat, halo, st, t)
      import :: integrator_t, model_t, local_lattice_t, halo_t, state_t, wp
      class(integrator_t), intent(inout) :: this
      type(model_t), intent(inout) :: model
      type(local_lattice_t), intent(in) :: lat
      type(halo_t), intent(inout) :: halo
      type(state_t), intent(inout) :: st
      real(wp), intent(in) :: t
    end subroutine integrator_resume_i
  end interface

contains

  !> Whether the last step stands, once every rank agrees (an integrator whose agreement
  !> completes later overrides this; here every step stands when step returns).
  subroutine integrator_settle(this, st, accepted)
    class(integrator_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    logical, intent(out) :: accepted
    accepted = .true.
  end subroutine integrator_settle

  !> After settle rejected the last step (the step that ended at t), before rejected: bring a
  !> state left part way into the next step (next_plain) back to that step's end (here: none
  !> is left so).
  subroutine integrator_rewind(this, model, lat, halo, st, t)
    class(integrator_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t
  end subroutine integrator_rewind

  !> With local, after this rank rejected a step: leave the verdict clear and the state and
  !> rates finite, so that the rank goes on stepping (what it computes until the driver's
  !> agreement is thrown away) without a non-finite value reaching its neighbours (here:
  !> nothing is kept of the verdict).
  subroutine integrator_carry_on(this, st)
    class(integrator_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
  end subroutine integrator_carry_on

  !> The half step h of the kicks around a state of a run of step dt, which the energy balance
  !> takes the kinetic energy (1/2) m (|v|^2 - h^2 |a|^2) at (the one its steps' work
  !> balances); here 0: the state's own kinetic energy (an integrator with kicks overrides it).
  pure real(wp) function integrator_kick_half(this, dt) result(h)
    class(integrator_t), intent(in) :: this
    real(wp), intent(in) :: dt
    h = 0.0_wp
  end function integrator_kick_half

  !> Set the communicator over which the integrator agrees on a step's acceptance.
  subroutine integrator_init(this, comm)
    class(integrator_t), intent(inout) :: this
    type(MPI_Comm), intent(in) :: comm
    this%comm = comm
  end subroutine integrator_init
end module iem_integrator
