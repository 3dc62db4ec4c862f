!> Velocity Verlet (kick-drift-kick) step of the lattice: one force evaluation a step, second
!> order, symplectic when undamped; damping forces use the half-step velocity.
module iem_verlet
  use iem_kinds, only: wp
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_state, only: state_t
  use iem_timers, only: timer_start, timer_stop, t_force, t_halo, t_update
  implicit none
  private
  public :: verlet_step

contains

  !> Advance y from t to t + dt, given in st%acc the rates at (u(t), damping velocity of the
  !> previous half step) from state_rate or the previous call; leaves in st%acc the rates at
  !> t + dt. With capped damping the filter w relaxes exactly towards the half-step velocity.
  !> Accumulates the local external work and damping dissipation of the step.
  subroutine verlet_step(model, lat, halo, st, t, dt, w_ext, w_damp)
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    real(wp) :: p_ext, p_damp, h, c
    integer :: l, n

    n = lat%n_owned
    h = 0.5_wp*dt
    call timer_start(t_update)
    ! kick: v(t + dt/2); prescribed velocities take their mid-step values before the drift
    do l = 1, n
      st%y(3:4, l) = st%y(3:4, l) + h*st%acc(1:2, l)
    end do
    call model%prescribe(st%y, t + h)
    ! drift: u(t + dt)
    do l = 1, n
      st%y(1:2, l) = st%y(1:2, l) + dt*st%y(3:4, l)
    end do
    if (model%omega_cap > 0.0_wp) then
      c = 1.0_wp - exp(-model%omega_cap*dt)
      do l = 1, n
        st%y(5:6, l) = st%y(5:6, l) + c*(st%y(3:4, l) - st%y(5:6, l))
      end do
    end if
    call timer_stop(t_update)
    call timer_start(t_halo)
    call halo%exchange(st%y)
    call timer_stop(t_halo)
    call timer_start(t_force)
    ! the end of the step is accepted: nonlinear springs commit their history to it
    call model%rate(lat, st%y, t + dt, st%acc, p_ext, p_damp, commit=.true.)
    call timer_stop(t_force)
    call timer_start(t_update)
    ! the powers are those of the half-step velocity: exact work of constant forces
    w_ext = w_ext + dt*p_ext
    w_damp = w_damp + dt*p_damp
    ! kick: v(t + dt)
    do l = 1, n
      st%y(3:4, l) = st%y(3:4, l) + h*st%acc(1:2, l)
    end do
    call model%prescribe(st%y, t + dt)
    call timer_stop(t_update)
  end subroutine verlet_step
end module iem_verlet
