!> How the ranks of a run on more than one rank agree on a non-finite step without a reduction
!> every step (docs/architecture.md, "How the ranks agree on a non-finite step"): each rank
!> keeps its own verdict (the integrator's local), the first step it rejected, and goes on
!> stepping on finite values; the ranks agree on the first rejected step only at the steps
!> that read the state (a sample, a frame, a checkpoint's look, a repartitioning, the last
!> step); a run that diverged steps again, bit for bit and without output, from its origin
!> (its last checkpoint, or the initial state) to the step before the rejected one, which the
!> ranks then reject together as on one rank (stop_rejected), so that the message and the
!> last frame are the same.
submodule (iem_simulation) iem_simulation_agreement
  use mpi_f08, only: MPI_MIN, MPI_INTEGER8
  use iem_checkpoint, only: checkpoint_read_header
  use iem_integrator_factory, only: integrator_create
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure agree_steps
    integer(i8) :: first
    stat = 0
    msg = ''
    call MPI_Allreduce(this%k_bad, first, 1, MPI_INTEGER8, MPI_MIN, this%comm)
    if (first == huge(1_i8)) return
    call replay(this, first, stat, msg)
  end procedure agree_steps

  !> Documented at its interface in iem_simulation.f90.
  module procedure step_rejected
    if (.not. this%integ%local) then
      call stop_rejected(this, k, t, stat, msg)
      return
    end if
    stat = 0
    msg = ''
    this%k_bad = min(this%k_bad, k)
    call this%integ%carry_on(this%st)
  end procedure step_rejected

  !> Some rank rejected step k_fail (the first): load the origin (a checkpoint at step k0 <
  !> k_fail, or the initial state, k0 = 0), make the integrator anew with the verdict agreed
  !> every step, and step again to k_fail without samples, frames, checkpoints or
  !> repartitioning, the driver's choices otherwise the same (its next_plain), so that the
  !> ranks reject step k_fail together and stop_rejected names it and writes the last good
  !> state. Collective.
  subroutine replay(this, k_fail, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer(i8), intent(in) :: k_fail
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(checkpoint_header_t) :: h
    real(wp) :: t, t_prev, w_ext, w_damp
    character(len=:), allocatable :: why, from
    integer(i8) :: k, k0
    logical :: accepted

    msg = 'the solution diverged: non-finite values at step '//itoa(k_fail)//' on some rank'
    if (len(this%origin) == 0) then
      k0 = 0
      from = 'the initial state'
    else
      call checkpoint_read_header(this%origin, this%comm, h, stat, why)
      if (stat /= 0) then
        stat = 3
        msg = msg//"; the checkpoint to step again from to the last good state, '"// &
              this%origin//"', "//why
        return
      end if
      k0 = h%step
      from = 'the checkpoint '//this%origin//' at step '//itoa(k0)
    end if
    call log_info('step '//itoa(k_fail)//' is not finite on some rank: stepping again from '// &
                  from//' to write the last good state')
    if (len(this%origin) == 0) then
      call initial_state(this, stat, why)
    else
      call read_state(this, this%origin, h, stat, why)
    end if
    if (stat /= 0) then
      stat = 3
      msg = msg//'; loading '//from//' to step again from failed: '//why
      return
    end if
    this%k_bad = huge(1_i8)
    deallocate(this%integ)
    call integrator_create(this%cfg%run%integrator, this%comm, this%integ)
    if (k0 > 0) call this%integ%resume(this%model, this%lat, this%halo, this%st, h%t)
    w_ext = 0.0_wp
    w_damp = 0.0_wp
    t_prev = real(k0 - 1, wp)*this%dt
    do k = k0, k_fail
      t = real(k, wp)*this%dt
      if (mod(k, int(work_collect_steps, i8)) == 0) call this%model%collect_work(this%lat)
      ! (what the evaluations compute as the first time: the same paths, the same bits)
      this%model%energies_due = sample_due(this, k, t_prev, t)
      call this%integ%prepare(this%model, this%lat, this%halo, this%st, t, this%dt, k == 0)
      call this%integ%settle(this%st, accepted)
      if (.not. accepted) then
        call stop_rejected(this, k, t, stat, msg)
        return
      end if
      if (k == k_fail) exit
      call plan_next(this, k, t)
      call this%integ%step(this%model, this%lat, this%halo, this%st, t, this%dt, w_ext, &
                           w_damp, accepted)
      t_prev = t
    end do
    stat = 3
    msg = msg//', but stepping again from '//from//' did not reproduce it (a run that is '// &
          'not deterministic: please report it); the output ends with the last frame '// &
          'written before'
  end subroutine replay

  !> The model and the state made again as the set-up and the start of the run made them
  !> (model%init, allocate_state), on the present lattice: the initial state is the
  !> configuration's, whatever the partition, and every evolving value (the springs' history,
  !> the damage, the work done) starts from it as at step 0. Collective.
  subroutine initial_state(this, stat, msg)
    type(simulation_t), intent(inout) :: this
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(alloc_guard_t) :: guard
    integer(i8), allocatable :: n_selected(:)
    allocate(n_selected(size(this%cfg%bcs) + size(this%cfg%loads)))
    this%model = model_t()
    call this%model%init(this%cfg, this%body, this%lat, n_selected, guard)
    call guard%agree(this%comm, this%grid%label(), stat, msg)
    if (stat /= 0) return
    call allocate_state(this, stat, msg)
  end subroutine initial_state
end submodule iem_simulation_agreement
