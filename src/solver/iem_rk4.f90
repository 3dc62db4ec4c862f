!> Classical explicit 4th-order Runge-Kutta step of the first-order system (u, v), with a halo
!> exchange before every stage's force evaluation; stage 1 is the rates iem_state's state_rate
!> forms (rk4_finish_step's caller), which rk4_t's prepare fuses with its update. rk4_t
!> puts it behind iem_integrator's interface: it rejects a step whose new state is not finite.
module iem_rk4
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_Iallreduce, MPI_Wait, MPI_Request, MPI_LOGICAL, MPI_LAND, &
                     MPI_STATUS_IGNORE, MPI_F_sync_reg
  use iem_kinds, only: wp
  use iem_constants, only: rk4_imag_limit
  use iem_stable_dt, only: rk4_stable_dt
  use iem_integrator, only: integrator_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_state, only: state_t
  use iem_timers, only: timer_start, timer_stop, t_force, t_update
  use iem_node_pass, only: rk4_stage_t
  use iem_node_pass_filtered, only: rk4_filtered_update, rk4_filtered_last_update
  implicit none
  private
  public :: rk4_t, rk4_finish_step

  !> The classical scheme's weights w_s and stage offsets (fractions of dt).
  real(wp), parameter :: weight(4) = [1.0_wp, 2.0_wp, 2.0_wp, 1.0_wp]/6.0_wp
  real(wp), parameter :: frac(4) = [0.0_wp, 0.5_wp, 0.5_wp, 1.0_wp]

  !> Classical RK4 as an integrator_t: rates evaluated at the top of every step, stages 2-4
  !> and the update in step, which accepts only a finite new state. Each rank tests its own
  !> new state; the ranks agree on it with a non-blocking reduction that completes behind the
  !> next step's halo exchange (settle), before anything overwrites the state it replaced
  !> (with local, not: the verdict is the rank's, and the driver agrees later).
  type, extends(integrator_t) :: rk4_t
    !> Whether stage 1 of the next step goes with its stages 2-4 as one wavefront (the model's
    !> rate_stages): set by a step that nothing follows but the next one (next_plain), where
    !> the wavefront applies; prepare then only settles the last step.
    logical :: deferred = .false.
    !> The agreement on the last step: pending, this rank's verdict, every rank's, whether
    !> this rank swapped its new state in, and the request.
    logical :: pending = .false., mine = .true., all = .true., swapped = .false.
    type(MPI_Request) :: req
  contains
    procedure :: name => rk4_name
    procedure :: stable_dt => rk4_dt
    procedure :: undamped_dt => rk4_undamped_dt
    procedure :: work_arrays => rk4_true
    procedure :: rejected => rk4_rejected
    procedure :: prepare => rk4_prepare
    procedure :: step => rk4_step
    procedure :: resume => rk4_resume
    procedure :: settle => rk4_settle
    procedure :: carry_on => rk4_carry_on
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

  !> True: RK4 needs the stage arrays of the state.
  pure logical function rk4_true(this)
    class(rk4_t), intent(in) :: this
    rk4_true = .true.
  end function rk4_true

  !> Stage 1 at every step: the rates at y(t), which also serve the step's sample, with the
  !> stage's update (st%ynew and the stage state st%ys for dt) fused into the evaluation's
  !> pass over the nodes (4 state values a node, or 6 with capped damping); or, with the
  !> stages deferred to the step's wavefront, only the last step's agreement settled.
  subroutine rk4_prepare(this, model, lat, halo, st, t, dt, first)
    class(rk4_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    logical, intent(in) :: first
    type(rk4_stage_t) :: stage
    logical :: ok
    if (this%deferred) then
      call this%settle(st, ok)
      return
    end if
    stage%stage = 1
    stage%wdt = weight(1)*dt
    stage%h = frac(2)*dt
    ! the last step's agreement is waited for inside the evaluation, after its halo exchange
    ! and cell forces and before its pass overwrites the state the step replaced
    call timer_start(t_force)
    if (this%pending) then
      call model%rate(lat, st%y, t, st%acc, st%p_ext1, st%p_damp1, commit=.true., stage=stage, &
                      ynew=st%ynew, ynext=st%ys, halo=halo, vote=this%req, vote_all=this%all)
      this%pending = .false.
      call this%settle(st, ok)
    else
      call model%rate(lat, st%y, t, st%acc, st%p_ext1, st%p_damp1, commit=.true., stage=stage, &
                      ynew=st%ynew, ynext=st%ys, halo=halo)
    end if
    call timer_stop(t_force)
  end subroutine rk4_prepare

  !> Stages 2-4 and the update: a finite new state is swapped in on this rank, and the ranks'
  !> agreement is started (settle completes it; accepted is .true. until then); with local,
  !> accepted is this rank's verdict.
  subroutine rk4_step(this, model, lat, halo, st, t, dt, w_ext, w_damp, accepted)
    class(rk4_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    logical, intent(out) :: accepted
    call rk4_finish_step(model, lat, halo, st, t, dt, w_ext, w_damp, this%mine, .true., &
                         this%deferred)
    this%deferred = .false.
    if (this%next_plain) this%deferred = model%stages_fit(lat, size(st%y, 1))
    if (this%local) then
      ! (this rank's verdict: a rejected state was not swapped in, y is the one before)
      this%swapped = .false.
      this%all = this%mine
      accepted = this%mine
      return
    end if
    this%swapped = this%mine
    call MPI_Iallreduce(this%mine, this%all, 1, MPI_LOGICAL, MPI_LAND, this%comm, this%req)
    this%pending = .true.
    accepted = .true.
  end subroutine rk4_step

  !> After a rejected step with local: y already holds the finite state before it (the next
  !> step starts from there again); only the verdict is cleared.
  subroutine rk4_carry_on(this, st)
    class(rk4_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    this%mine = .true.
    this%all = .true.
  end subroutine rk4_carry_on

  !> Complete the ranks' agreement on the last step (at once if already complete); when some
  !> rank's new state was not finite, every rank goes back: y holds the state before the
  !> step again and st%ynew the rejected one, and accepted is .false. (until the next step).
  subroutine rk4_settle(this, st, accepted)
    class(rk4_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    logical, intent(out) :: accepted
    real(wp), allocatable :: swap(:, :)
    if (this%pending) then
      call MPI_Wait(this%req, MPI_STATUS_IGNORE)
      call MPI_F_sync_reg(this%all)
      this%pending = .false.
    end if
    if (.not. this%all .and. this%swapped) then
      call move_alloc(st%y, swap)
      call move_alloc(st%ynew, st%y)
      call move_alloc(swap, st%ynew)
      this%swapped = .false.
    end if
    accepted = this%all
  end subroutine rk4_settle

  !> After a rejected step: y is already the state before it (back = 1); the first owned node
  !> whose rejected state (st%ynew) holds a non-finite value.
  subroutine rk4_rejected(this, st, n, back, first_bad, note)
    class(rk4_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    integer, intent(in) :: n
    integer, intent(out) :: back, first_bad
    character(len=:), allocatable, intent(out) :: note
    integer :: l
    back = 1
    note = ''
    first_bad = 0
    do l = 1, n
      if (.not. all(ieee_is_finite(st%ynew(:, l)))) then
        first_bad = l
        exit
      end if
    end do
  end subroutine rk4_rejected

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
  !> external work and damping dissipation of the step with the same weights. Each stage's
  !> update of the new state and of the next stage state is one pass over the nodes; the
  !> accepted new state is swapped in (no copy). With finite present, the new state is
  !> accepted only if all its owned values are finite (finite = .false.: y keeps the state at
  !> t and st%ynew holds the rejected one); the test is summed in the last pass.
  subroutine rk4_finish_step(model, lat, halo, st, t, dt, w_ext, w_damp, finite, fused, &
                             stage1)
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    logical, intent(out), optional :: finite
    !> Stage 1's update was fused into prepare's evaluation, and the later ones are too.
    logical, intent(in), optional :: fused
    !> Stage 1 was left to this call (with fused, where the model's stages_fit): it goes with
    !> stages 2-4 as one wavefront (st%p_ext1 and st%p_damp1 are set here).
    logical, intent(in), optional :: stage1
    real(wp) :: p_ext, p_damp, total, pw_ext(4), pw_damp(4)
    integer :: n, stage, first
    logical :: fuse
    type(rk4_stage_t) :: stg

    n = lat%n_owned
    fuse = .false.
    if (present(fused)) fuse = fused
    call timer_start(t_update)
    ! k1 is in st%acc (accelerations) and st%y(3:4) (velocities), or already applied
    first = 2
    if (fuse .and. present(stage1)) then
      if (stage1) first = 1
    end if
    if (.not. fuse) call stage_update(st%y, st%y, st%acc, weight(1)*dt, frac(2)*dt, .true., &
                                      st%ynew, st%ys, total)
    if (first == 2) then
      w_ext = w_ext + weight(1)*dt*st%p_ext1
      ! (stage 1's work counts from here, after the step's sample: not folded in prepare)
      call model%add_work(lat, weight(1)*dt)
      w_damp = w_damp + weight(1)*dt*st%p_damp1
    end if
    if (fuse .and. (first == 1 .or. model%stages_fit(lat, size(st%y, 1)))) then
      ! stages first..4 as one wavefront over the bands: the same operations, bit for bit
      if (first == 2) call model%prescribe(st%ys, t + frac(2)*dt)
      call timer_stop(t_update)
      call timer_start(t_force)
      call model%rate_stages(lat, first, st%ys, st%y, st%ynew, st%acc, t + frac*dt, &
                             weight*dt, [frac(2:4)*dt, 0.0_wp], pw_ext, pw_damp, total, &
                             halo)
      call timer_stop(t_force)
      call timer_start(t_update)
      if (first == 1) then
        st%p_ext1 = pw_ext(1)
        st%p_damp1 = pw_damp(1)
      end if
      do stage = first, 4
        w_ext = w_ext + weight(stage)*dt*pw_ext(stage)
        w_damp = w_damp + weight(stage)*dt*pw_damp(stage)
      end do
      call finish()
      return
    end if
    do stage = 2, 4
      call model%prescribe(st%ys, t + frac(stage)*dt)
      call timer_stop(t_update)
      call timer_start(t_force)
      if (fuse) then
        stg%stage = stage
        stg%wdt = weight(stage)*dt
        stg%h = 0.0_wp
        if (stage < 4) stg%h = frac(stage + 1)*dt
        call model%rate(lat, st%ys, t + frac(stage)*dt, st%acc, p_ext, p_damp, stage=stg, &
                        y0=st%y, ynew=st%ynew, halo=halo, fold=stg%wdt)
        total = stg%total
      else
        call model%rate(lat, st%ys, t + frac(stage)*dt, st%acc, p_ext, p_damp, halo=halo)
      end if
      call timer_stop(t_force)
      call timer_start(t_update)
      w_ext = w_ext + weight(stage)*dt*p_ext
      call model%add_work(lat, weight(stage)*dt, folded=fuse)
      w_damp = w_damp + weight(stage)*dt*p_damp
      if (fuse) cycle
      if (stage < 4) then
        call stage_update(st%y, st%ys, st%acc, weight(stage)*dt, frac(stage + 1)*dt, .false., &
                          st%ynew, st%ys, total)
      else
        call last_update(st%ys, st%acc, weight(stage)*dt, st%ynew, total)
      end if
    end do
    call finish()
  contains

    !> The new state swapped in (with finite, only when all its values are finite; total is
    !> their sum), its prescribed velocities set.
    subroutine finish()
      real(wp), allocatable :: swap(:, :)
      if (present(finite)) then
        ! any NaN or Inf (or an overflow) makes the sum non-finite
        finite = ieee_is_finite(total)
        if (.not. finite) then
          call timer_stop(t_update)
          return
        end if
      end if
      call move_alloc(st%y, swap)
      call move_alloc(st%ynew, st%y)
      call move_alloc(swap, st%ynew)
      call model%prescribe(st%y, t + dt)
      call timer_stop(t_update)
    end subroutine finish

    !> One pass over the owned nodes for the rate (velocities ys(3:4), rates acc) of a stage:
    !> ynew <- (first: y, else ynew) + wdt (ys(3:4), acc), and the next stage state
    !> ys <- y + h (ys(3:4), acc) (ys may be the stage state itself: each node's values are
    !> read before they are written).
    subroutine stage_update(y, yk, acc, wdt, h, first, ynew, ys, total)
      real(wp), intent(in), contiguous :: y(:, :), yk(:, :), acc(:, :)
      real(wp), intent(in) :: wdt, h
      logical, intent(in) :: first
      real(wp), intent(inout), contiguous :: ynew(:, :), ys(:, :)
      real(wp), intent(out) :: total
      real(wp) :: v1, v2, a1, a2
      integer :: l, ns
      ns = size(y, 1)
      total = 0.0_wp
      if (ns == 4) then
        if (first) then
          do l = 1, n
            v1 = yk(3, l)
            v2 = yk(4, l)
            a1 = acc(1, l)
            a2 = acc(2, l)
            ynew(1, l) = y(1, l) + wdt*v1
            ynew(2, l) = y(2, l) + wdt*v2
            ynew(3, l) = y(3, l) + wdt*a1
            ynew(4, l) = y(4, l) + wdt*a2
            ys(1, l) = y(1, l) + h*v1
            ys(2, l) = y(2, l) + h*v2
            ys(3, l) = y(3, l) + h*a1
            ys(4, l) = y(4, l) + h*a2
          end do
        else
          do l = 1, n
            v1 = yk(3, l)
            v2 = yk(4, l)
            a1 = acc(1, l)
            a2 = acc(2, l)
            ynew(1, l) = ynew(1, l) + wdt*v1
            ynew(2, l) = ynew(2, l) + wdt*v2
            ynew(3, l) = ynew(3, l) + wdt*a1
            ynew(4, l) = ynew(4, l) + wdt*a2
            ys(1, l) = y(1, l) + h*v1
            ys(2, l) = y(2, l) + h*v2
            ys(3, l) = y(3, l) + h*a1
            ys(4, l) = y(4, l) + h*a2
          end do
        end if
      else
        ! capped damping's filtered velocities (6 values): the operations of the fused passes
        call rk4_filtered_update(n, merge(1, 0, first), wdt, h, y, yk, acc, ynew, ys)
      end if
    end subroutine stage_update

    !> The last stage's pass: ynew <- ynew + wdt (ys(3:4), acc), with the sum of the new
    !> values in total (eight partial sums, so the loop vectorises).
    subroutine last_update(ys, acc, wdt, ynew, total)
      real(wp), intent(in), contiguous :: ys(:, :), acc(:, :)
      real(wp), intent(in) :: wdt
      real(wp), intent(inout), contiguous :: ynew(:, :)
      real(wp), intent(out) :: total
      real(wp) :: part(8)
      integer :: l, l0, j, ns
      ns = size(ys, 1)
      if (ns == 6) then
        ! capped damping's filtered velocities: the operations of the fused pass
        call rk4_filtered_last_update(n, wdt, ys, acc, ynew, total)
        return
      end if
      do l = 1, n
        ynew(1, l) = ynew(1, l) + wdt*ys(3, l)
        ynew(2, l) = ynew(2, l) + wdt*ys(4, l)
        ynew(3:ns, l) = ynew(3:ns, l) + wdt*acc(:, l)
      end do
      part = 0.0_wp
      do l0 = 0, n - 1, 8
        do j = 1, min(8, n - l0)
          part(j) = part(j) + sum(ynew(:, l0 + j))
        end do
      end do
      total = sum(part)
    end subroutine last_update
  end subroutine rk4_finish_step
end module iem_rk4
