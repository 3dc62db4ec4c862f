!> Classical explicit 4th-order Runge-Kutta step of the first-order system (u, v), with a halo
!> exchange before every stage's force evaluation; stage 1 is iem_state's state_rate. rk4_t
!> puts it behind iem_integrator's interface: it rejects a step whose new state is not finite.
module iem_rk4
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_Allreduce, MPI_IN_PLACE, MPI_LOGICAL, MPI_LAND
  use iem_kinds, only: wp
  use iem_constants, only: rk4_imag_limit
  use iem_stable_dt, only: rk4_stable_dt
  use iem_integrator, only: integrator_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_state, only: state_t, state_rate
  use iem_timers, only: timer_start, timer_stop, t_force, t_halo, t_update
  implicit none
  private
  public :: rk4_t, rk4_finish_step

  !> Classical RK4 as an integrator_t: rates evaluated at the top of every step, stages 2-4
  !> and the update in step, which accepts only a finite new state (one reduction a step).
  type, extends(integrator_t) :: rk4_t
  contains
    procedure :: name => rk4_name
    procedure :: stable_dt => rk4_dt
    procedure :: undamped_dt => rk4_undamped_dt
    procedure :: work_arrays => rk4_true
    procedure :: rejects_nonfinite => rk4_true
    procedure :: prepare => rk4_prepare
    procedure :: step => rk4_step
    procedure :: resume => rk4_resume
  end type rk4_t

contains

  !> 'RK4'.
  function rk4_name(this) result(name)
    class(rk4_t), intent(in) :: this
    character(len=:), allocatable :: name
    name = 'RK4'
  end function rk4_name

  !> RK4's stable step with damping (iem_stable_dt's rk4_stable_dt).
  pure real(wp) function rk4_dt(this, omega_max, alpha, beta, omega_cap)
    class(rk4_t), intent(in) :: this
    real(wp), intent(in) :: omega_max, alpha, beta, omega_cap
    rk4_dt = rk4_stable_dt(omega_max, alpha, beta, omega_cap)
  end function rk4_dt

  !> RK4's stable step without damping: its reach on the imaginary axis over omega_max.
  pure real(wp) function rk4_undamped_dt(this, omega_max)
    class(rk4_t), intent(in) :: this
    real(wp), intent(in) :: omega_max
    rk4_undamped_dt = rk4_imag_limit/omega_max
  end function rk4_undamped_dt

  !> True: RK4 needs the stage arrays of the state, and rejects non-finite new states.
  pure logical function rk4_true(this)
    class(rk4_t), intent(in) :: this
    rk4_true = .true.
  end function rk4_true

  !> Stage 1 at every step: the rates at y(t) (state_rate), which also serve the step's sample.
  subroutine rk4_prepare(this, model, lat, halo, st, t, first)
    class(rk4_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t
    logical, intent(in) :: first
    call state_rate(model, lat, halo, st, t)
  end subroutine rk4_prepare

  !> Stages 2-4 and the update, accepted only when every rank's new state is finite.
  subroutine rk4_step(this, model, lat, halo, st, t, dt, w_ext, w_damp, accepted)
    class(rk4_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    logical, intent(out) :: accepted
    call rk4_finish_step(model, lat, halo, st, t, dt, w_ext, w_damp, accepted)
    call MPI_Allreduce(MPI_IN_PLACE, accepted, 1, MPI_LOGICAL, MPI_LAND, this%comm)
  end subroutine rk4_step

  !> Nothing: prepare evaluates the rates of the loaded state at the first step.
  subroutine rk4_resume(this, model, lat, halo, st, t)
    class(rk4_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t
  end subroutine rk4_resume

  !> Stages 2-4 and the update y <- y + dt/6 (k1 + 2 k2 + 2 k3 + k4); accumulates the local
  !> external work and damping dissipation of the step with the same weights. With finite
  !> present, the new state is accepted only if all its owned values are finite (finite =
  !> .false.: y keeps the state at t and st%ynew holds the rejected one).
  subroutine rk4_finish_step(model, lat, halo, st, t, dt, w_ext, w_damp, finite)
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    logical, intent(out), optional :: finite
    real(wp) :: p_ext, p_damp, h, total
    integer :: l, n, stage, ns
    real(wp), parameter :: weight(4) = [1.0_wp, 2.0_wp, 2.0_wp, 1.0_wp]/6.0_wp
    real(wp), parameter :: frac(4) = [0.0_wp, 0.5_wp, 0.5_wp, 1.0_wp]

    n = lat%n_owned
    ns = size(st%y, 1)
    call timer_start(t_update)
    ! k1 is in st%acc (accelerations) and st%y(3:4) (velocities)
    do l = 1, n
      st%ynew(1:2, l) = st%y(1:2, l) + weight(1)*dt*st%y(3:4, l)
      st%ynew(3:ns, l) = st%y(3:ns, l) + weight(1)*dt*st%acc(:, l)
      st%ys(1:2, l) = st%y(1:2, l) + frac(2)*dt*st%y(3:4, l)
      st%ys(3:ns, l) = st%y(3:ns, l) + frac(2)*dt*st%acc(:, l)
    end do
    w_ext = w_ext + weight(1)*dt*st%p_ext1
    call model%add_work(lat, weight(1)*dt)
    w_damp = w_damp + weight(1)*dt*st%p_damp1
    do stage = 2, 4
      call model%prescribe(st%ys, t + frac(stage)*dt)
      call timer_stop(t_update)
      call timer_start(t_halo)
      call halo%exchange(st%ys)
      call timer_stop(t_halo)
      call timer_start(t_force)
      call model%rate(lat, st%ys, t + frac(stage)*dt, st%acc, p_ext, p_damp)
      call timer_stop(t_force)
      call timer_start(t_update)
      w_ext = w_ext + weight(stage)*dt*p_ext
      call model%add_work(lat, weight(stage)*dt)
      w_damp = w_damp + weight(stage)*dt*p_damp
      do l = 1, n
        st%ynew(1:2, l) = st%ynew(1:2, l) + weight(stage)*dt*st%ys(3:4, l)
        st%ynew(3:ns, l) = st%ynew(3:ns, l) + weight(stage)*dt*st%acc(:, l)
      end do
      if (stage < 4) then
        h = frac(stage + 1)*dt
        do l = 1, n
          st%ys(1:2, l) = st%y(1:2, l) + h*st%ys(3:4, l)
          st%ys(3:ns, l) = st%y(3:ns, l) + h*st%acc(:, l)
        end do
      end if
    end do
    if (present(finite)) then
      ! any NaN or Inf (or an overflow) makes the sum non-finite
      total = 0.0_wp
      do l = 1, n
        total = total + sum(st%ynew(:, l))
      end do
      finite = ieee_is_finite(total)
      if (.not. finite) then
        call timer_stop(t_update)
        return
      end if
    end if
    st%y(:, 1:n) = st%ynew
    call model%prescribe(st%y, t + dt)
    call timer_stop(t_update)
  end subroutine rk4_finish_step
end module iem_rk4
