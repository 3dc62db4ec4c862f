!> Velocity Verlet (kick-drift-kick) step of the lattice: one force evaluation a step, second
!> order, symplectic when undamped; damping forces use the half-step velocity. verlet_t puts
!> it behind iem_integrator's interface: it updates the state in place, and a step whose new
!> velocities are not finite somewhere is rejected on every rank, its last good state rebuilt
!> from what the guarded kick left (no copy of the state is kept). When nothing reads the state
!> between two steps (the driver's next_plain) the next step's first kick and drift run in the
!> same pass over the nodes as this step's second kick (bit for bit the same values; one pass
!> over the state a step instead of two); where the model can (one rank, bands, elastic), that
!> pass goes band by band with the next step's cell forces a band behind (the model's
!> verlet_pair), so that each step is one sweep over the state.
module iem_verlet
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_Request, MPI_Iallreduce, MPI_Wait, MPI_STATUS_IGNORE, MPI_LOGICAL, &
                     MPI_LAND, MPI_F_sync_reg
  use iem_kinds, only: wp
  use iem_stable_dt, only: verlet_stable_dt
  use iem_integrator, only: integrator_t
  use iem_local_lattice, only: local_lattice_t
  use iem_halo, only: halo_t
  use iem_model, only: model_t
  use iem_state, only: state_t, state_rate
  use iem_timers, only: timer_start, timer_stop, t_force, t_update
  use iem_node_pass, only: kick_drift, guarded_kick
  implicit none
  private
  public :: verlet_t, verlet_step

  !> Velocity Verlet as an integrator_t: one force evaluation a step, whose rates carry over
  !> to the next step; no stage arrays. The second kick of a step is guarded (where its new
  !> velocities are not finite the rates array keeps the half-step ones); the ranks agree on
  !> the step with a non-blocking reduction that settle completes at the top of the next step,
  !> before the state moves again (with local, not: the verdict is the rank's, and the driver
  !> agrees later).
  type, extends(integrator_t) :: verlet_t
    !> The agreement on the last step (or on the rates of the start): pending, this rank's
    !> verdict, every rank's, and the request.
    logical :: pending = .false., mine = .true., all = .true.
    type(MPI_Request) :: req
    !> This rank's first owned node with a non-finite new value (0: none), and the half step
    !> of the last kick (0: the rates of the start were evaluated, nothing was kicked).
    integer :: first_bad = 0
    real(wp) :: h = 0.0_wp
    !> Whether the state is part way into the next step: the last step's pass also ran the
    !> next step's first kick and drift (its rates then cleared where it did).
    logical :: ahead = .false.
    !> Whether the last step also summed this step's cell forces into the rates (the model's
    !> verlet_pair), so that this step's evaluation goes on from them.
    logical :: paired = .false.
  contains
    procedure :: name => verlet_name
    procedure :: stable_dt => verlet_dt
    procedure :: undamped_dt => verlet_undamped_dt
    procedure :: work_arrays => verlet_false
    procedure :: rejected => verlet_rejected
    procedure :: settle => verlet_settle
    procedure :: prepare => verlet_prepare
    procedure :: step => verlet_accept_step
    procedure :: resume => verlet_resume
    procedure :: rewind => verlet_rewind
    procedure :: kick_half => verlet_kick_half
    procedure :: carry_on => verlet_carry_on
  end type verlet_t

contains

  !> 'velocity Verlet'.
  function verlet_name(this) result(name)
    class(verlet_t), intent(in) :: this
    character(len=:), allocatable :: name
    name = 'velocity Verlet'
  end function verlet_name

  !> Velocity Verlet's stable step with damping (iem_stable_dt's verlet_stable_dt).
  pure real(wp) function verlet_dt(this, omega_max, alpha, beta, omega_cap)
    class(verlet_t), intent(in) :: this
    real(wp), intent(in) :: omega_max, alpha, beta, omega_cap
    verlet_dt = verlet_stable_dt(omega_max, alpha, beta, omega_cap)
  end function verlet_dt

  !> Velocity Verlet's stable step without damping: 2/omega_max.
  pure real(wp) function verlet_undamped_dt(this, omega_max)
    class(verlet_t), intent(in) :: this
    real(wp), intent(in) :: omega_max
    verlet_undamped_dt = 2.0_wp/omega_max
  end function verlet_undamped_dt

  !> dt/2: the kicks around a state at t_n take the velocities v(t_n -+ dt/2) = v -+ (dt/2) a,
  !> and the steps' work balances (1/2) m v(t_n - dt/2).v(t_n + dt/2) = (1/2) m (|v|^2 -
  !> (dt/2)^2 |a|^2) (docs/model.md, "Time integration").
  pure real(wp) function verlet_kick_half(this, dt) result(h)
    class(verlet_t), intent(in) :: this
    real(wp), intent(in) :: dt
    h = 0.5_wp*dt
  end function verlet_kick_half

  !> False: Verlet needs no stage arrays (it updates the state in place).
  pure logical function verlet_false(this)
    class(verlet_t), intent(in) :: this
    verlet_false = .false.
  end function verlet_false

  !> The rates at y(t): evaluated at the first step of the run only (and agreed on, like a
  !> step: settle rejects them when not finite on some rank); later the previous step has left
  !> them in st%acc (and a restart has loaded them from the checkpoint).
  subroutine verlet_prepare(this, model, lat, halo, st, t, dt, first)
    class(verlet_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    logical, intent(in) :: first
    integer :: l
    if (.not. first) return
    this%ahead = .false.
    this%paired = .false.
    call state_rate(model, lat, halo, st, t)
    this%first_bad = 0
    do l = 1, lat%n_owned
      if (.not. all(ieee_is_finite(st%acc(:, l)))) then
        this%first_bad = l
        exit
      end if
    end do
    this%h = 0.0_wp
    call vote(this)
  end subroutine verlet_prepare

  !> One velocity Verlet step (verlet_step); the ranks' agreement on it is started (settle
  !> completes it; accepted is .true. until then); with local, accepted is this rank's
  !> verdict.
  subroutine verlet_accept_step(this, model, lat, halo, st, t, dt, w_ext, w_damp, accepted)
    class(verlet_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    logical, intent(out) :: accepted
    logical :: ahead, pair
    ahead = this%next_plain
    if (ahead) ahead = can_run_ahead(model, st, t, this%t_next, dt)
    ! the next step's cell forces in this step's sweep: where the model can, when no sample
    ! reads the next step's evaluation (next_forces)
    pair = ahead .and. this%next_forces .and. .not. model%energies_due
    if (pair) pair = model%pair_fits(lat, size(st%y, 1))
    call verlet_step(model, lat, halo, st, t, dt, w_ext, w_damp, this%first_bad, this%ahead, &
                     ahead, this%t_next, this%paired, pair)
    this%ahead = ahead
    this%paired = pair
    this%h = 0.5_wp*dt
    call vote(this)
    ! (this rank's verdict with local; else settle's, the reduction still pending)
    accepted = .true.
    if (this%local) accepted = this%all
  end subroutine verlet_accept_step

  !> Whether a step from t whose end the driver numbers t_next may run the next step's first
  !> kick and drift in its pass: a state of 4 values a node with the forces summed into the
  !> rates (the fused passes), no stiffness damping (rewind finds the last good state from the
  !> forces at rest), and no support released from t to one step past t_next (where the next
  !> step's first kick would use the imposed acceleration).
  logical function can_run_ahead(model, st, t, t_next, dt) result(ok)
    type(model_t), intent(in) :: model
    type(state_t), intent(in) :: st
    real(wp), intent(in) :: t, t_next, dt
    ok = size(st%y, 1) == 4 .and. model%sum_in_acc .and. model%beta == 0.0_wp
    if (ok) ok = .not. any(model%bc_release > t .and. model%bc_release <= t_next + dt)
  end function can_run_ahead

  !> Start the ranks' agreement on this rank's verdict (first_bad == 0); one still pending
  !> (a caller that did not settle) is completed first, and a rejection it brings stands.
  subroutine vote(this)
    class(verlet_t), intent(inout) :: this
    call complete(this)
    this%mine = this%first_bad == 0 .and. this%all
    if (this%local) then
      this%all = this%mine
      return
    end if
    call MPI_Iallreduce(this%mine, this%all, 1, MPI_LOGICAL, MPI_LAND, this%comm, this%req)
    this%pending = .true.
  end subroutine vote

  !> Complete the ranks' agreement on the last step (at once if already complete): accepted
  !> is .false. on every rank when some rank's new values were not finite.
  subroutine verlet_settle(this, st, accepted)
    class(verlet_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    logical, intent(out) :: accepted
    call complete(this)
    accepted = this%all
  end subroutine verlet_settle

  !> Wait for the pending agreement, if any.
  subroutine complete(this)
    class(verlet_t), intent(inout) :: this
    if (.not. this%pending) return
    call MPI_Wait(this%req, MPI_STATUS_IGNORE)
    call MPI_F_sync_reg(this%all)
    this%pending = .false.
  end subroutine complete

  !> After a rejected step: the last good state is the step's own displacements (finite: the
  !> previous step's velocities were) with the velocities of the half step before it: v - h a
  !> where the kick gave finite velocities (to the round-off of the kick), else the ones the
  !> guarded kick kept in acc (exact); back = 0. After rejected rates of the start, y is the
  !> initial state itself.
  subroutine verlet_rejected(this, st, n, back, first_bad, note)
    class(verlet_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    integer, intent(in) :: n
    integer, intent(out) :: back, first_bad
    character(len=:), allocatable, intent(out) :: note
    integer :: l
    back = 0
    first_bad = this%first_bad
    note = ''
    if (this%h == 0.0_wp) return
    note = ', its velocities those of the half step before it'
    do l = 1, n
      if (ieee_is_finite(st%y(3, l)) .and. ieee_is_finite(st%y(4, l))) then
        st%y(3:4, l) = st%y(3:4, l) - this%h*st%acc(1:2, l)
      else
        st%y(3:4, l) = st%acc(1:2, l)
      end if
    end do
    this%h = 0.0_wp
  end subroutine verlet_rejected

  !> After a rejected step with local: the verdict cleared, and every value of the state and
  !> the rates of this rank's owned nodes that is not finite set to 0, so that the rank goes on
  !> stepping on finite values (they are thrown away: the driver steps again to the rejected
  !> step).
  subroutine verlet_carry_on(this, st)
    class(verlet_t), intent(inout) :: this
    type(state_t), intent(inout) :: st
    where (.not. ieee_is_finite(st%y)) st%y = 0.0_wp
    where (.not. ieee_is_finite(st%acc)) st%acc = 0.0_wp
    this%first_bad = 0
    this%mine = .true.
    this%all = .true.
  end subroutine verlet_carry_on

  !> After settle rejected the step that ended at t, when its pass ran ahead into the next
  !> step: each node that pass moved on (finite velocities) back to the step's end, to the
  !> round-off: u - dt v, and the half-step velocity w from v = w + 2 h a with a = a0 - alpha w,
  !> a0 the accelerations of the forces at those displacements (one evaluation, at rest: no
  !> stiffness damping runs ahead); its rates cleared, so that rejected keeps w. The other
  !> nodes kept what the guarded kick left. The prescribed velocities: those of the half step.
  subroutine verlet_rewind(this, model, lat, halo, st, t)
    class(verlet_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t
    real(wp), allocatable :: ys(:, :), a0(:, :)
    logical, allocatable :: moved(:)
    real(wp) :: p_ext, p_damp, h
    integer :: l, n
    if (.not. this%ahead) return
    this%ahead = .false.
    n = lat%n_owned
    h = this%h
    allocate(moved(n), a0(size(st%acc, 1), size(st%acc, 2)))
    do l = 1, n
      moved(l) = ieee_is_finite(st%y(3, l)) .and. ieee_is_finite(st%y(4, l))
      if (moved(l)) st%y(1:2, l) = st%y(1:2, l) - 2.0_wp*h*st%y(3:4, l)
    end do
    ys = st%y
    ys(3:4, :) = 0.0_wp
    a0 = 0.0_wp
    call model%rate(lat, ys, t, a0, p_ext, p_damp, halo=halo)
    do l = 1, n
      if (.not. moved(l)) cycle
      st%y(3:4, l) = (st%y(3:4, l) - 2.0_wp*h*a0(1:2, l))/(1.0_wp - 2.0_wp*h*model%alpha)
      st%acc(:, l) = 0.0_wp
    end do
    call model%prescribe(st%y, t - h)
  end subroutine verlet_rewind

  !> Verlet does not evaluate the rates at the step it starts from (they are in the
  !> checkpoint): one trial evaluation, into a scratch array and without commit, gives the
  !> model the strain energy of the loaded state.
  subroutine verlet_resume(this, model, lat, halo, st, t)
    class(verlet_t), intent(inout) :: this
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t
    real(wp), allocatable :: scratch(:, :)
    real(wp) :: p_ext, p_damp
    ! (zero: the model may sum the forces into it)
    allocate(scratch(size(st%acc, 1), size(st%acc, 2)), source=0.0_wp)
    ! (not overlapped: model_rate's halo would count this untimed evaluation in the timers)
    call halo%exchange(st%y)
    call model%rate(lat, st%y, t, scratch, p_ext, p_damp, record=.true.)
  end subroutine verlet_resume

  !> Advance y from t to t + dt, given in st%acc the rates at (u(t), damping velocity of the
  !> previous half step) from state_rate or the previous call; leaves in st%acc the rates at
  !> t + dt. With capped damping the filter w relaxes exactly towards the half-step velocity.
  !> Accumulates the local external work and damping dissipation of the step. The second
  !> kick is guarded (iem_node_pass's kick_node: where the new velocities are not finite the
  !> rates keep the half-step ones): first_bad is the first owned node where they are not (0:
  !> none), and then the step's prescribed values are left as the kick left them. With begun,
  !> the previous call ran this step's first kick and drift (the state is at its drift, the
  !> rates cleared). With ahead (4 values a node, forces summed into the rates; the next
  !> step starts at t_next), this step's pass runs the next step's first kick and drift where
  !> its kick was finite, with the next step's prescribed values, and clears the rates there:
  !> the state is then the next call's with begun, bit for bit. With ready, the rates hold the
  !> cell forces at t + dt already (the last call's pair); with pair (and ahead), the pass runs
  !> band by band and the next step's cell forces follow into the rates (the model's
  !> verlet_pair: the next call's with ready, bit for bit), and pair says on return whether
  !> they are there.
  subroutine verlet_step(model, lat, halo, st, t, dt, w_ext, w_damp, first_bad, begun, ahead, &
                         t_next, ready, pair)
    type(model_t), intent(inout) :: model
    type(local_lattice_t), intent(in) :: lat
    type(halo_t), intent(inout) :: halo
    type(state_t), intent(inout) :: st
    real(wp), intent(in) :: t, dt
    real(wp), intent(inout) :: w_ext, w_damp
    integer, intent(out), optional :: first_bad
    logical, intent(in), optional :: begun, ahead
    real(wp), intent(in), optional :: t_next
    logical, intent(in), optional :: ready
    logical, intent(inout), optional :: pair
    real(wp) :: p_ext, p_damp, h, c, u_bc(size(model%bc_node))
    integer :: l, n, bad
    logical :: fuse, start, next, done, two

    n = lat%n_owned
    h = 0.5_wp*dt
    fuse = size(st%y, 1) == 4
    start = .true.
    if (present(begun)) start = .not. begun
    next = .false.
    if (present(ahead)) next = ahead
    done = .false.
    if (present(ready)) done = ready
    two = .false.
    if (present(pair)) then
      two = pair .and. next
      pair = .false.
    end if
    if (next .and. .not. (fuse .and. model%sum_in_acc .and. present(t_next))) &
      error stop 'verlet_step: ahead needs 4 values a node, the forces in the rates and t_next'
    call timer_start(t_update)
    if (start) then
      ! kick: v(t + dt/2); prescribed velocities take their mid-step values before the drift;
      ! drift: u(t + dt)
      if (fuse) then
        ! one pass; the prescribed dofs are mended from their displacements before it
        call keep_prescribed(model, st%y, u_bc)
        call kick_drift(n, h, dt, st%acc, st%y, clear=model%sum_in_acc)
        call mend_prescribed(model, st%y, u_bc, t, dt)
      else
        do l = 1, n
          st%y(3:4, l) = st%y(3:4, l) + h*st%acc(1:2, l)
        end do
        call model%prescribe(st%y, t + h)
        do l = 1, n
          st%y(1:2, l) = st%y(1:2, l) + dt*st%y(3:4, l)
        end do
      end if
      if (model%omega_cap > 0.0_wp) then
        c = 1.0_wp - exp(-model%omega_cap*dt)
        do l = 1, n
          st%y(5:6, l) = st%y(5:6, l) + c*(st%y(3:4, l) - st%y(5:6, l))
        end do
      end if
    end if
    call timer_stop(t_update)
    call timer_start(t_force)
    ! the powers of the loads, reactions and capped damping: those of the forces' mean over
    ! the step, which the kicks apply half a step each around v(t + dt/2) (docs/model.md)
    model%mean_dt = dt
    ! the end of the step is accepted: nonlinear springs commit their history to it; with 4
    ! values a node the kick v(t + dt) is fused into the evaluation's pass over the nodes
    if (two) then
      ! (the prescribed dofs mended as the bands' passes go)
      call keep_prescribed(model, st%y, u_bc)
      call model%verlet_pair(lat, st%y, t + dt, t_next, h, dt, st%acc, u_bc, done, &
                             p_ext, p_damp, bad, pair)
    else if (next) then
      ! (the next step's first part: the prescribed dofs mended from their displacements here)
      call keep_prescribed(model, st%y, u_bc)
      call model%rate(lat, st%y, t + dt, st%acc, p_ext, p_damp, commit=.true., kick=h, &
                      halo=halo, first_bad=bad, drift=dt, cells_done=done, fold=dt)
    else if (fuse) then
      call model%rate(lat, st%y, t + dt, st%acc, p_ext, p_damp, commit=.true., kick=h, &
                      halo=halo, first_bad=bad, cells_done=done, fold=dt)
    else
      call model%rate(lat, st%y, t + dt, st%acc, p_ext, p_damp, commit=.true., halo=halo, &
                      fold=dt)
    end if
    model%mean_dt = 0.0_wp
    call timer_stop(t_force)
    call timer_start(t_update)
    ! the powers of the step's mean forces at the half-step velocity
    w_ext = w_ext + dt*p_ext
    w_damp = w_damp + dt*p_damp
    ! (each evaluation above folded its nodes' mass damping work with the weight dt)
    call model%add_work(lat, dt, folded=.true.)
    ! kick: v(t + dt)
    if (.not. fuse) call guarded_kick(n, h, st%acc, st%y, bad)
    if (present(first_bad)) first_bad = bad
    ! (a rejected step keeps what the guarded kick left, for rejected)
    ! (with two, the bands' passes mended the prescribed dofs as they went)
    if (bad == 0 .and. .not. two) then
      if (next) then
        call mend_prescribed(model, st%y, u_bc, t_next, dt)
      else
        call model%prescribe(st%y, t + dt)
      end if
    end if
    call timer_stop(t_update)
  end subroutine verlet_step

  !> The displacements u_bc of the prescribed dofs (before a kick and drift moves them).
  pure subroutine keep_prescribed(model, y, u_bc)
    type(model_t), intent(in) :: model
    real(wp), intent(in) :: y(:, :)
    real(wp), intent(out) :: u_bc(:)
    integer :: q
    do q = 1, size(model%bc_node)
      u_bc(q) = y(model%bc_comp(q), model%bc_node(q))
    end do
  end subroutine keep_prescribed

  !> After the kick and drift of a step from t (of dt): the prescribed velocities at the half
  !> step, and the prescribed displacements u_bc + dt v of the dofs not yet released then.
  subroutine mend_prescribed(model, y, u_bc, t, dt)
    type(model_t), intent(in) :: model
    real(wp), intent(inout) :: y(:, :)
    real(wp), intent(in) :: u_bc(:), t, dt
    real(wp) :: h
    integer :: q, l, c2
    h = 0.5_wp*dt
    call model%prescribe(y, t + h)
    do q = 1, size(model%bc_node)
      l = model%bc_node(q)
      c2 = model%bc_comp(q)
      if (t + h >= model%bc_release(model%bc_id(q))) cycle
      y(c2, l) = u_bc(q) + dt*y(2 + c2, l)
    end do
  end subroutine mend_prescribed
end module iem_verlet
