!> Reports of a run on rank 0: its start, progress and performance, and the names
!> and limits of the integrator for messages.
submodule (iem_simulation) iem_simulation_report
  use mpi_f08, only: MPI_SUM
  use iem_kinds, only: mpi_wp
  use iem_build_info, only: iem_version
  use iem_timers, only: timer_total, timer_names, n_timers, peak_rss_bytes
  implicit none

contains

  !> Log the size of the run, its time step and its damping (rank 0).
  module procedure report_start
    call log_info('iem '//iem_version//': '//itoa(this%body%n_nodes)//' nodes, '// &
      itoa(this%body%n_cells)//' cells ('//itoa(this%grid%nx)//' x '//itoa(this%grid%ny)// &
      '), '//itoa(this%n_ranks)//' ranks')
    call log_info('time step '//rtoa(this%dt)//' s = '// &
      rtoa(this%dt/this%dt_limit)//' of the '//integrator_name(this)//' limit '// &
      rtoa(this%dt_limit)// &
      ' s (omega_max '//rtoa(this%omega_max)//' rad/s); '//itoa(this%n_steps)//' steps to '// &
      rtoa(this%cfg%run%t_end)//' s')
    if (this%model%alpha > 0.0_wp .or. this%model%beta > 0.0_wp) then
      call log_info('Rayleigh damping: alpha = '//rtoa(this%model%alpha)//' 1/s, beta = '// &
                    rtoa(this%model%beta)//' s')
      if (this%model%omega_cap > 0.0_wp) call log_info('stiffness damping acts on the '// &
        'velocity filtered at '//rtoa(this%cfg%damping%cap_frequency)//' Hz (capped)')
      call log_info('damped stable step '//rtoa(this%dt_limit)//' s = '// &
        rtoa(this%dt_limit/undamped_limit(this))//' of the undamped one')
    end if
  end procedure report_start

  !> Rank 0 reports throughput, where the time went (largest over ranks) and peak memory.
  module procedure report_performance
    real(wp) :: t(n_timers), mem(2), work
    character(len=300) :: line
    character(len=8) :: pct
    integer :: k
    do k = 1, n_timers
      t(k) = timer_total(k)
    end do
    call MPI_Allreduce(MPI_IN_PLACE, t, n_timers, mpi_wp(), MPI_MAX, this%comm)
    mem = real(peak_rss_bytes(), wp)/1048576.0_wp
    call MPI_Allreduce(MPI_IN_PLACE, mem(1), 1, mpi_wp(), MPI_MAX, this%comm)
    call MPI_Allreduce(MPI_IN_PLACE, mem(2), 1, mpi_wp(), MPI_SUM, this%comm)
    work = real(this%body%n_nodes, wp)*real(this%n_steps, wp)
    write(line, '(a,es10.3,a,es10.3,a,es10.3,a,es10.3,a)') 'performance: ', work, &
      ' node-steps in ', wall, ' s: ', work/wall, ' node-steps/s (', &
      work/wall/this%n_ranks, ' per rank)'
    call log_info(trim(line))
    line = 'time in'
    do k = 1, n_timers
      write(pct, '(f6.1)') 100.0_wp*t(k)/wall
      line = trim(line)//' '//trim(timer_names(k))//' '//trim(adjustl(pct))//'%'
      if (k < n_timers) line = trim(line)//','
    end do
    call log_info(trim(line)//' (largest over ranks)')
    write(line, '(a,f0.1,a,f0.1,a)') 'memory: peak ', max(mem(1), 0.1_wp), &
      ' MB per rank (largest), ', max(mem(2), 0.1_wp), ' MB in all'
    call log_info(trim(line))
  end procedure report_performance

  !> Rank 0: print a progress line at every 10% of the run and every progress_interval s.
  module procedure progress
    real(wp) :: now, frac, eta
    character(len=200) :: line
    now = MPI_Wtime()
    frac = real(k, wp)/real(this%n_steps, wp)
    if (frac + 1.0e-12_wp < next_report .and. now - wall_last < this%cfg%run%progress_interval &
        .and. k /= this%n_steps) return
    do while (next_report <= frac + 1.0e-12_wp)
      next_report = next_report + 0.1_wp
    end do
    wall_last = now
    eta = 0.0_wp
    if (k > 0) eta = (now - wall0)*(1.0_wp - frac)/frac
    write(line, '(a,i0,a,i0,a,es10.3,a,es9.2,a,f9.1,a,f9.1,a,es9.2)') 'step ', k, '/', &
      this%n_steps, '  t ', t, ' s  dt ', this%dt, ' s  wall ', now - wall0, ' s  eta ', eta, &
      ' s  energy error ', this%last_balance
    call log_info(trim(line))
  end procedure progress

  !> 'RK4' or 'velocity Verlet': the integrator of a dynamic run, for messages.
  module procedure integrator_name
    name = this%integ%name()
  end procedure integrator_name

  !> The integrator's stable step without damping.
  real(wp) function undamped_limit(this) result(dt)
    type(simulation_t), intent(in) :: this
    dt = this%integ%undamped_dt(this%omega_max)
  end function undamped_limit

end submodule iem_simulation_report
