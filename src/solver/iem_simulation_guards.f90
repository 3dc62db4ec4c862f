!> Guards of a dynamic run: non-finite states and the energy balance, which stop the
!> run naming where it diverged and writing the last good state as a frame. Which state is
!> the last good one depends on the integrator: y itself when it rejects non-finite steps
!> (RK4), else the copy kept here at every check (velocity Verlet).
submodule (iem_simulation) iem_simulation_guards
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use mpi_f08, only: MPI_INTEGER8, MPI_MIN, MPI_2DOUBLE_PRECISION, MPI_MAXLOC
  use iem_logger, only: log_warn
  use iem_lattice_queries, only: node_place
  implicit none

contains

  !> Documented at its interface in iem_simulation.f90.
  module procedure init_guards
    integer :: ierr, n
    n = merge(0, this%lat%n_owned, this%integ%rejects_nonfinite())
    allocate(this%snap(4, n), stat=ierr)
    call guard%note(ierr, 'the copy of the last good state', 32.0_wp*this%lat%n_owned)
    if (ierr == 0) this%snap = 0.0_wp
  end procedure init_guards

  !> Documented at its interface in iem_simulation.f90.
  module procedure keep_good_state
    if (this%integ%rejects_nonfinite()) return
    this%snap = this%st%y(1:4, 1:this%lat%n_owned)
    this%snap_step = k
    this%snap_time = t
  end procedure keep_good_state

  !> Documented at its interface in iem_simulation.f90.
  module procedure check_state
    integer :: n
    logical :: finite
    stat = 0
    msg = ''
    ! an integrator that rejects non-finite steps has checked every state it accepted
    if (this%integ%rejects_nonfinite()) return
    n = this%lat%n_owned
    finite = all(ieee_is_finite(this%st%y(1:4, 1:n)))
    call MPI_Allreduce(MPI_IN_PLACE, finite, 1, MPI_LOGICAL, MPI_LAND, this%comm)
    if (.not. finite) then
      call stop_nonfinite(this, k, t, this%st%y, this%snap, this%snap_step, this%snap_time, &
                          stat, msg)
      return
    end if
    call keep_good_state(this, k, t)
  end procedure check_state

  !> Documented at its interface in iem_simulation.f90.
  module procedure stop_diverged
    if (this%integ%rejects_nonfinite()) then
      ! only finite states were accepted: the energies overflowed
      call stop_nonfinite(this, k, t, this%st%y, this%st%y(1:4, 1:this%lat%n_owned), k, t, &
                          stat, msg)
    else
      call stop_nonfinite(this, k, t, this%st%y, this%snap, this%snap_step, this%snap_time, &
                          stat, msg)
    end if
  end procedure stop_diverged

  !> Documented at its interface in iem_simulation.f90.
  module procedure stop_rejected
    call stop_nonfinite(this, k + 1, t + this%dt, this%st%ynew, &
                        this%st%y(1:4, 1:this%lat%n_owned), k, t, stat, msg)
  end procedure stop_rejected

  !> Documented at its interface in iem_simulation.f90.
  module procedure stop_nonfinite
    integer(i8) :: first, mine
    integer :: l, owner, stat2
    real(wp) :: xy(2), big(2)
    character(len=:), allocatable :: msg2
    mine = huge(1_i8)
    do l = 1, this%lat%n_owned
      if (.not. all(ieee_is_finite(bad(1:4, l)))) then
        mine = this%lat%gid(l)
        exit
      end if
    end do
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
      if (norm2(good(3:4, l)) > big(1)) big = [norm2(good(3:4, l)), real(this%lat%gid(l), wp)]
    end do
    call MPI_Allreduce(MPI_IN_PLACE, big, 1, MPI_2DOUBLE_PRECISION, MPI_MAXLOC, this%comm)
    xy = node_place(this%lat, this%comm, int(big(2), i8))
    msg = msg//', with dt = '//rtoa(this%dt)//' s (stability limit '//rtoa(this%dt_limit)// &
          ' s); in the last good state (step '//itoa(k_good)//', written as the last '// &
          'frame) the fastest node was '//itoa(int(big(2), i8))//' (x = '//rtoa(xy(1))// &
          ', y = '//rtoa(xy(2))//' m, speed '//rtoa(big(1))//' m/s)'
    call flush_history(this, stat2)
    call this%out%write_frame(k_good, t_good, good(1:2, :), good(3:4, :), stat2, msg2)
  end procedure stop_nonfinite

  !> Documented at its interface in iem_simulation.f90.
  module procedure energy_guard
    real(wp) :: err, fast(2), xy(2)
    integer :: l, stat2
    logical :: warn, halt
    character(len=:), allocatable :: where, msg2
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
                                                       real(this%lat%gid(l), wp)]
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
