!> The state of one rank for the explicit integrators: y = (u_x, u_y, v_x, v_y[, w_x, w_y])
!> per local node (w: the filtered velocity of capped damping), the rates of the last force
!> evaluation, and the work arrays RK4 needs beside them.
module iem_state
  use iem_kinds, only: wp
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_timers, only: timer_start, timer_stop, t_force
  use iem_alloc_guard, only: alloc_guard_t
  implicit none
  private
  public :: state_t, state_rate

  !> State vectors of one rank (owned nodes first, then halo nodes).
  type :: state_t
    !> State at the start of the step (owned and halo nodes).
    real(wp), allocatable :: y(:, :)
    !> RK4 only: stage state (owned and halo nodes).
    real(wp), allocatable :: ys(:, :)
    !> RK4 only: accumulated new state (owned nodes; halo columns unused), swapped with y when
    !> a step is accepted; after a rejected step, the rejected one.
    real(wp), allocatable :: ynew(:, :)
    !> Rates of rows 3: of the last evaluation (owned nodes): accelerations[, filter rates].
    real(wp), allocatable :: acc(:, :)
    !> Local power of external forces and of damping at the evaluation of state_rate.
    real(wp) :: p_ext1 = 0.0_wp, p_damp1 = 0.0_wp
  contains
    procedure :: init => state_init
  end type state_t

contains

  !> Allocate the state for n_local nodes of which n_owned are owned, with n_state values a
  !> node (default 4), all zero; rk4_work (default true) adds RK4's two work arrays; n_rates
  !> (default n_owned) is the number of columns of acc: 0 for RK4 with 4 values a node (its
  !> updates are fused into the evaluations' passes, which never read it), n_local for velocity
  !> Verlet when the forces are summed into it (model_t's sum_in_acc). A failed allocation is
  !> handed to guard (nothing allocated then); without guard it stops the program.
  subroutine state_init(this, n_owned, n_local, n_state, rk4_work, guard, n_rates)
    class(state_t), intent(inout) :: this
    integer, intent(in) :: n_owned, n_local
    integer, intent(in), optional :: n_state
    logical, intent(in), optional :: rk4_work
    type(alloc_guard_t), intent(inout), optional :: guard
    integer, intent(in), optional :: n_rates
    type(alloc_guard_t) :: g
    integer :: ns, ierr, na
    logical :: work
    ns = 4
    if (present(n_state)) ns = n_state
    work = .true.
    if (present(rk4_work)) work = rk4_work
    if (allocated(this%y)) deallocate(this%y, this%acc)
    if (allocated(this%ys)) deallocate(this%ys, this%ynew)
    na = n_owned
    if (present(n_rates)) na = n_rates
    allocate(this%y(ns, n_local), this%acc(ns - 2, na), stat=ierr)
    call g%note(ierr, 'the state of the rank', 8.0_wp*ns*n_local + 8.0_wp*(ns - 2)*na)
    if (work .and. .not. g%failed) then
      allocate(this%ys(ns, n_local), this%ynew(ns, n_local), stat=ierr)
      call g%note(ierr, 'the RK4 work arrays of the rank', 16.0_wp*ns*n_local)
      if (g%failed) deallocate(this%y, this%acc)
    end if
    if (g%failed) then
      call g%pass(guard)
      return
    end if
    this%y = 0.0_wp
    this%acc = 0.0_wp
    if (work) then
      this%ys = 0.0_wp
      this%ynew = 0.0_wp
    end if
  end subroutine state_init

  !> Exchange the halo of y and evaluate the rates at time t into st%acc (with the powers p_ext1,
  !> p_damp1; the exchange overlaps the evaluation): the first stage of a step, kept apart so the
  !> caller can record the energies and output of the state y, which this evaluation provides. y is
  !> an accepted state: nonlinear springs commit their history to it.
  subroutine state_rate(model, lat, halo, st, t)
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t
    call timer_start(t_force)
    call model%rate(lat, st%y, t, st%acc, st%p_ext1, st%p_damp1, commit=.true., halo=halo)
    call timer_stop(t_force)
  end subroutine state_rate
end module iem_state
