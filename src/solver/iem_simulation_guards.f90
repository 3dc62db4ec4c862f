!> Guards of a dynamic run: non-finite states and the energy balance, which stop the
!> run naming where it diverged and writing the last good state as a frame. Every integrator
!> rejects a step whose new values are not finite (on every rank) and says which state is the
!> last good one (RK4: that of the step before; velocity Verlet: the rejected step's
!> displacements with the velocities of the half step before them); no copy is kept here.
submodule (iem_simulation) iem_simulation_guards
  use mpi_f08, only: MPI_INTEGER8, MPI_MIN, MPI_2DOUBLE_PRECISION, MPI_MAXLOC
  use iem_logger, only: log_warn
  use iem_lattice_queries, only: node_place
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure stop_diverged
    integer :: n
    ! every accepted state was finite: the energies overflowed; the state is the last good one
    n = this%lat%n_owned
    call stop_nonfinite(this, k, t, 0, this%st%y(:, 1:n), k, t, '', stat, msg)
  end procedure stop_diverged

  !> Documented at its interface in iem_simulation.f90.
  module procedure stop_rejected
    integer :: back, first_bad, n
    character(len=:), allocatable :: note
    n = this%lat%n_owned
    call this%integ%rewind(this%model, this%lat, this%halo, this%st, t)
    call this%integ%rejected(this%st, n, back, first_bad, note)
    call stop_nonfinite(this, k, t, first_bad, this%st%y(:, 1:n), k - back, &
                        t - back*this%dt, note, stat, msg)
  end procedure stop_rejected

  !> Documented at its interface in iem_simulation.f90.
  module procedure stop_nonfinite
    integer(i8) :: first, mine
    integer :: l, owner, stat2
    real(wp) :: xy(2), big(2)
    character(len=:), allocatable :: msg2
    mine = huge(1_i8)
    if (first_bad > 0) mine = this%lat%node_gid(first_bad)
    call MPI_Allreduce(mine, first, 1, MPI_INTEGER8, MPI_MIN, this%comm)
    owner = -1
    if (mine == first) owner = this%rank
    call MPI_Allreduce(MPI_IN_PLACE, owner, 1, MPI_INTEGER, MPI_MAX, this%comm)
    stat = 3
    if (first == huge(1_i8)) then
      msg = 'the solution diverged (non-finite energy) at step '//itoa(k)//', t = '//rtoa(t)//' s'
    else
      xy = node_place(this%lat, this%comm, first)
      msg = 'the solution diverged: non-finite values at step '//itoa(k)//', t = '//rtoa(t)// &
            ' s, first at node '//itoa(first)//' (x = '//rtoa(xy(1))//', y = '//rtoa(xy(2))// &
            ' m) on rank '//itoa(owner)
    end if
    ! where the growth was largest in the last good state
    big = [-1.0_wp, -1.0_wp]
    do l = 1, this%lat%n_owned
      if (norm2(good(3:4, l)) > big(1)) big = [norm2(good(3:4, l)), real(this%lat%node_gid(l), wp)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, big, 1, MPI_2DOUBLE_PRECISION, MPI_MAXLOC, this%comm)
    xy = node_place(this%lat, this%comm, int(big(2), i8))
    msg = msg//', with dt = '//rtoa(this%dt)//' s (stability limit '//rtoa(this%dt_limit)// &
          ' s); in the last good state (step '//itoa(k_good)//', written as the last '// &
          'frame'//note//') the fastest node was '//itoa(int(big(2), i8))//' (x = '// &
          rtoa(xy(1))//', y = '//rtoa(xy(2))//' m, speed '//rtoa(big(1))//' m/s)'
    call flush_history(this, stat2)
    call this%out%write_frame(k_good, t_good, good, good, stat2, msg2, u_row=1, v_row=3)
  end procedure stop_nonfinite

  !> Documented at its interface in iem_simulation.f90.
  module procedure energy_guard
    real(wp) :: err, fast(2), xy(2)
    integer :: l, stat2
    logical :: warn, halt
    character(len=:), allocatable :: where
    stat = 0
    msg = ''
    err = this%last_balance
    warn = this%cfg%run%energy_warn > 0.0_wp .and. err > this%cfg%run%energy_warn .and. &
           .not. this%warned
    halt = this%cfg%run%energy_stop > 0.0_wp .and. err > this%cfg%run%energy_stop
    if (.not. (warn .or. halt)) return
    ! the fastest node: (speed, global index) with MAXLOC
    fast = [-1.0_wp, -1.0_wp]
    do l = 1, this%lat%n_owned
      if (norm2(this%st%y(3:4, l)) > fast(1)) fast = [norm2(this%st%y(3:4, l)), &
                                                       real(this%lat%node_gid(l), wp)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, fast, 1, MPI_2DOUBLE_PRECISION, MPI_MAXLOC, this%comm)
    xy = node_place(this%lat, this%comm, int(fast(2), i8))
    where = 'fastest node '//itoa(int(fast(2), i8))//' (x = '//rtoa(xy(1))//', y = '// &
            rtoa(xy(2))//' m, speed '//rtoa(fast(1))//' m/s)'
    if (halt) then
      stat = 3
      msg = 'energy-balance error '//rtoa(err)//' > energy_stop = '// &
            rtoa(this%cfg%run%energy_stop)//' at step '//itoa(k)//', t = '//rtoa(t)//' s; '// &
            where//'; dt = '//rtoa(this%dt)//' s (stability limit '//rtoa(this%dt_limit)// &
            ' s); the state at this step is the last frame'
      call flush_history(this, stat2)
      call write_frame(this, k, t, stat2)
      return
    end if
    this%warned = .true.
    call log_warn('energy-balance error '//rtoa(err)//' > energy_warn = '// &
                  rtoa(this%cfg%run%energy_warn)//' at step '//itoa(k)//', t = '//rtoa(t)// &
                  ' s; '//where//' (warned once; the run goes on)')
  end procedure energy_guard

end submodule iem_simulation_guards
